// Waitsets, read conditions and guard conditions: how a service's work loop sleeps.
#pragma once

#include "cdc/dds/entity.hpp"
#include "cdc/dds/participant.hpp"

#include <chrono>
#include <cstdint>
#include <vector>

namespace cdc::dds {

// A condition the application triggers itself (shutdown, "new work queued").
class GuardCondition {
 public:
  explicit GuardCondition(const Participant& participant);
  // Not tied to one participant: usable in a WaitSet() that spans domains.
  GuardCondition();
  void trigger();
  void reset();
  bool triggered() const;
  dds_entity_t handle() const noexcept { return cond_.handle(); }

 private:
  Entity cond_;
};

// Triggers while the reader holds any sample.
class ReadCondition {
 public:
  explicit ReadCondition(dds_entity_t reader);
  dds_entity_t handle() const noexcept { return cond_.handle(); }

 private:
  Entity cond_;
};

class WaitSet {
 public:
  explicit WaitSet(const Participant& participant);
  // A waitset for conditions of any participant in any domain (a service on two domains).
  WaitSet();
  // Attaches a condition or entity; wait() reports `tag` when it triggers.
  void attach(dds_entity_t entity, intptr_t tag);
  void detach(dds_entity_t entity);
  // Blocks until something triggers or timeout passes; returns the tags of what triggered.
  std::vector<intptr_t> wait(std::chrono::nanoseconds timeout);

 private:
  Entity ws_;
  size_t attached_ = 0;
};

}  // namespace cdc::dds
