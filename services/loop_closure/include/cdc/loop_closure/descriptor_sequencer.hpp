// Delivers every robot's descriptors in keyframe order, each once, and says which ones to ask for
// again. Descriptors travel volatile: a peer out of range misses them, and so can a reader that has
// not matched yet. Rather than have the DDS history replay everything a robot ever described on
// every reconnection (transient-local), a receiver that sees a gap asks the owner for just the
// missing range (cdc/place/descriptor_sync) and holds back what came after the gap until it is
// filled, so that the peers' pose-hint chains are built in order. A gap at the end (what a peer
// described out of range just before it stopped making keyframes: nothing comes after it to show
// it) is found from the owner's announced last keyframe (its robot status) and asked for the same
// way. Synchronous, no DDS.
#pragma once

#include "cdc/loop_closure/loop_core.hpp"

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <vector>

namespace cdc::loops {

struct SequencerParams {
  Nanos resend = std::chrono::seconds(2);  // a gap still open is asked for again after this
  int max_attempts = 5;                    // asks for one gap while its owner is in range, then skip it
  size_t max_held = 4096;                  // descriptors held back per robot; beyond, the gap is skipped
};

struct SyncWanted {
  uint32_t robot = 0;
  uint32_t first = 0, last = 0;  // keyframe ids, inclusive
};

struct SequencerStats {
  uint64_t delivered = 0, duplicates = 0, held = 0, sync_requests = 0, gaps_skipped = 0, ids_skipped = 0;
};

class DescriptorSequencer {
 public:
  explicit DescriptorSequencer(SequencerParams p = {}) : p_(p) {}

  // A descriptor in; the descriptors now deliverable, in keyframe order.
  std::vector<DescriptorIn> add(DescriptorIn d);

  // The ranges to ask for now (one per robot with a gap, at most every `resend`, and not while the
  // gap has been shrinking since the last ask: its answer is still arriving). A robot for which
  // `reachable` says false is not asked; a gap asked for `max_attempts` times while its owner was
  // reachable is given up, and what was held behind it is returned in `released`.
  std::vector<SyncWanted> wanted(Nanos now, const std::function<bool(uint32_t)>& reachable,
                                 std::vector<DescriptorIn>& released);

  // `robot` says it has made keyframes up to `last` (its status). Descriptors up to there that do not
  // come within `resend` of the last raise of this mark are a tail gap, asked for like any other.
  void announce(uint32_t robot, uint32_t last, Nanos now);

  // Descriptors known to exist and not yet delivered (behind gaps, held, or announced), all robots.
  uint64_t missing() const;

  // The next keyframe id expected from `robot` (0 for a robot never heard).
  uint32_t next_expected(uint32_t robot) const;
  size_t held(uint32_t robot) const;
  const SequencerStats& stats() const noexcept { return stats_; }

 private:
  struct Stream {
    uint32_t next = 0;                       // every id below it has been delivered (or skipped)
    std::map<uint32_t, DescriptorIn> ahead;  // held back behind a gap
    Nanos last_ask{Nanos::min()};
    uint32_t asked_for = 0;  // the gap start the attempts count for
    int attempts = 0;
    int64_t announced = -1;            // the owner's last keyframe, as it says (-1: not heard)
    Nanos announced_at{Nanos::min()};  // when `announced` was last raised
  };
  // The last id of the gap starting at s.next, if there is one to ask for now; -1 for none.
  int64_t gap_end(const Stream& s, Nanos now) const;
  void drain(Stream& s, std::vector<DescriptorIn>& out);
  void skip_gap(Stream& s, std::vector<DescriptorIn>& out);

  SequencerParams p_;
  std::map<uint32_t, Stream> streams_;
  SequencerStats stats_;
};

}  // namespace cdc::loops
