// The loops this service wrote, kept so that the ones a peer back in reach may have missed can be
// written to it again. PeerReach decides which and when; this holds the messages, by a handle of
// their own (loop sequence numbers start again with each incarnation), and lets go of a message
// once PeerReach forgets its loop.
#pragma once

#include "cdc/dds/types.hpp"
#include "cdc/loop_closure/peer_reach.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

namespace cdc::loops {

class WrittenLoops {
 public:
  // reach outlives this.
  explicit WrittenLoops(PeerReach& reach) : reach_(&reach) {}

  // m was written now: an accepted loop, or the withdrawal of one.
  void wrote(const cdc_msg_LoopClosure& m, bool withdrawal, Nanos now);
  // The loops to write again now, in the order they were first written.
  std::vector<const cdc_msg_LoopClosure*> due(Nanos now);
  // Messages held.
  size_t size() const noexcept { return loops_.size(); }

 private:
  PeerReach* reach_;
  std::map<uint64_t, cdc_msg_LoopClosure> loops_;  // by handle
  uint64_t next_ = 0;
};

}  // namespace cdc::loops
