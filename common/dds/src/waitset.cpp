#include "cdc/dds/waitset.hpp"

#include "cdc/dds/error.hpp"

namespace cdc::dds {

GuardCondition::GuardCondition(const Participant& participant)
    : cond_(check(dds_create_guardcondition(participant.handle()), "create guard condition")) {}

GuardCondition::GuardCondition()
    : cond_(check(dds_create_guardcondition(DDS_CYCLONEDDS_HANDLE), "create guard condition")) {}

void GuardCondition::trigger() { check(dds_set_guardcondition(cond_.handle(), true), "trigger guard condition"); }
void GuardCondition::reset() { check(dds_set_guardcondition(cond_.handle(), false), "reset guard condition"); }
bool GuardCondition::triggered() const {
  bool v = false;
  check(dds_read_guardcondition(cond_.handle(), &v), "read guard condition");
  return v;
}

ReadCondition::ReadCondition(dds_entity_t reader)
    : cond_(check(dds_create_readcondition(reader, DDS_ANY_STATE), "create read condition")) {}

WaitSet::WaitSet(const Participant& participant)
    : ws_(check(dds_create_waitset(participant.handle()), "create waitset")) {}

WaitSet::WaitSet() : ws_(check(dds_create_waitset(DDS_CYCLONEDDS_HANDLE), "create waitset")) {}

void WaitSet::attach(dds_entity_t entity, intptr_t tag) {
  check(dds_waitset_attach(ws_.handle(), entity, tag), "attach to waitset");
  ++attached_;
}

void WaitSet::detach(dds_entity_t entity) {
  check(dds_waitset_detach(ws_.handle(), entity), "detach from waitset");
  --attached_;
}

std::vector<intptr_t> WaitSet::wait(std::chrono::nanoseconds timeout) {
  std::vector<dds_attach_t> xs(attached_ == 0 ? 1 : attached_);
  const dds_return_t n =
      check(dds_waitset_wait(ws_.handle(), xs.data(), xs.size(), static_cast<dds_duration_t>(timeout.count())),
            "wait on waitset");
  std::vector<intptr_t> tags;
  tags.reserve(static_cast<size_t>(n));
  for (dds_return_t i = 0; i < n && static_cast<size_t>(i) < xs.size(); ++i) {
    tags.push_back(static_cast<intptr_t>(xs[static_cast<size_t>(i)]));
  }
  return tags;
}

}  // namespace cdc::dds
