#include "cdc/dds/qos.hpp"

#include "cdc/dds/pubsub.hpp"

#include <utility>

namespace cdc::dds {

namespace {
dds_duration_t to_dds(std::chrono::nanoseconds d) { return static_cast<dds_duration_t>(d.count()); }
}  // namespace

Qos::Qos() : qos_(dds_create_qos()) {}
Qos::~Qos() {
  if (qos_ != nullptr) {
    dds_delete_qos(qos_);
  }
}
Qos::Qos(const Qos& other) : qos_(dds_create_qos()) { dds_copy_qos(qos_, other.qos_); }
Qos& Qos::operator=(const Qos& other) {
  if (this != &other) {
    dds_reset_qos(qos_);
    dds_copy_qos(qos_, other.qos_);
  }
  return *this;
}
Qos::Qos(Qos&& other) noexcept : qos_(std::exchange(other.qos_, nullptr)) {}
Qos& Qos::operator=(Qos&& other) noexcept {
  std::swap(qos_, other.qos_);
  return *this;
}

Qos& Qos::reliable(std::chrono::milliseconds max_blocking) {
  dds_qset_reliability(qos_, DDS_RELIABILITY_RELIABLE, to_dds(max_blocking));
  return *this;
}
Qos& Qos::best_effort() {
  dds_qset_reliability(qos_, DDS_RELIABILITY_BEST_EFFORT, 0);
  return *this;
}
Qos& Qos::keep_last(int32_t depth) {
  dds_qset_history(qos_, DDS_HISTORY_KEEP_LAST, depth);
  return *this;
}
Qos& Qos::keep_all() {
  dds_qset_history(qos_, DDS_HISTORY_KEEP_ALL, DDS_LENGTH_UNLIMITED);
  return *this;
}
Qos& Qos::partitions(const std::vector<std::string>& names) {
  std::vector<const char*> ps;
  for (const auto& n : names) ps.push_back(n.c_str());
  dds_qset_partition(qos_, static_cast<uint32_t>(ps.size()), ps.data());
  return *this;
}

std::vector<std::string> Qos::partitions() const {
  uint32_t n = 0;
  char** ps = nullptr;
  std::vector<std::string> out;
  if (dds_qget_partition(qos_, &n, &ps)) {
    for (uint32_t i = 0; i < n; ++i) {
      out.emplace_back(ps[i]);
      dds_free(ps[i]);
    }
    dds_free(ps);
  }
  return out;
}

Qos& Qos::transient_local() {
  dds_qset_durability(qos_, DDS_DURABILITY_TRANSIENT_LOCAL);
  return *this;
}
Qos& Qos::volatile_durability() {
  dds_qset_durability(qos_, DDS_DURABILITY_VOLATILE);
  return *this;
}
Qos& Qos::liveliness_manual_by_topic(std::chrono::nanoseconds lease) {
  dds_qset_liveliness(qos_, DDS_LIVELINESS_MANUAL_BY_TOPIC, to_dds(lease));
  return *this;
}
Qos& Qos::liveliness_automatic(std::chrono::nanoseconds lease) {
  dds_qset_liveliness(qos_, DDS_LIVELINESS_AUTOMATIC, to_dds(lease));
  return *this;
}

namespace qos {

Qos sensor_stream(int32_t depth, bool reliable) {
  Qos q;
  if (reliable) {
    q.reliable();
  } else {
    q.best_effort();
  }
  q.keep_last(depth).volatile_durability();
  return q;
}

Qos keyed_state(int32_t depth) {
  Qos q;
  q.reliable().keep_last(depth).transient_local();
  return q;
}

Qos event_stream(int32_t depth) {
  Qos q;
  q.reliable().keep_last(depth).volatile_durability();
  return q;
}

Qos monitored_writer(std::chrono::nanoseconds lease) {
  Qos q = keyed_state(1);
  q.liveliness_manual_by_topic(lease);
  return q;
}

Qos monitored_reader() {
  // A reader requesting AUTOMATIC with an infinite lease matches every offered liveliness
  // (offered kind >= requested kind, offered lease <= requested lease).
  Qos q = keyed_state(1);
  dds_qset_liveliness(q.get(), DDS_LIVELINESS_AUTOMATIC, DDS_INFINITY);
  return q;
}

}  // namespace qos
namespace detail {
Entity make_group(const Participant& participant, const Qos& qos, bool publisher) {
  const std::vector<std::string> names = qos.partitions();
  if (names.empty()) return Entity();
  Qos group;
  group.partitions(names);
  const dds_entity_t e = publisher ? dds_create_publisher(participant.handle(), group.get(), nullptr)
                                   : dds_create_subscriber(participant.handle(), group.get(), nullptr);
  return Entity(check(e, publisher ? "create publisher" : "create subscriber"));
}
}  // namespace detail

namespace partitions {
std::string robot(uint32_t robot_id) { return "robot/" + std::to_string(robot_id); }
std::vector<std::string> own_reader(uint32_t robot_id) { return {robot(robot_id), ""}; }
std::vector<std::string> all_robots_reader() { return {kAllRobots, ""}; }
}  // namespace partitions

}  // namespace cdc::dds
