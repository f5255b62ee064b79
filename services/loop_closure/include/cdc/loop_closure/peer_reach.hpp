// Which peers the loop-closure service can reach, and which of its published loops a peer may have
// missed. Loops go out once, reliable but volatile: a peer whose link is cut longer than the DDS
// participant lease is unmatched, and whatever was written to it meanwhile (or just before, still
// unacknowledged) is gone. Rather than replay every loop on every reconnection (transient-local),
// when a peer is heard again after a silence the loops involving it that were written since shortly
// before the silence began are due again; receivers drop the copies they already hold (by sender,
// incarnation and sequence number). Loops are identified here by the caller's handle for the message it
// wrote (increasing; sequence numbers start again at 0 with each incarnation). At most `keep` loops are
// kept: the oldest beyond are forgotten (counted), so a peer silent for that long misses them. Synchronous,
// no DDS.
#pragma once

#include "cdc/loop_closure/loop_core.hpp"

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <vector>

namespace cdc::loops {

struct PeerReachParams {
  Nanos silence = std::chrono::seconds(3);        // a peer unheard this long is out of reach
  Nanos margin = std::chrono::seconds(2);         // loops written this long before a silence began may be lost too
  Nanos delay = std::chrono::milliseconds(1000);  // after hearing a peer again, wait this long (discovery matches
                                                  // its readers to the writer after its first samples arrive)
  size_t keep = 20000;                            // loops kept to be written again (~0.45 KB each with the message)
};

struct PeerReachStats {
  uint64_t silences = 0;   // a peer heard again after a silence
  uint64_t loops_due = 0;  // loops handed out to be written again (a loop due for two peers counts once)
  uint64_t forgotten = 0;  // loops dropped beyond `keep`, never to be written again
};

class PeerReach {
 public:
  explicit PeerReach(uint32_t me, PeerReachParams p = {}) : me_(me), p_(p) {}

  // This robot's own services always are in reach; a peer while heard within `silence`.
  bool in_reach(uint32_t robot, Nanos now) const;
  // Something came from `peer` (a descriptor, a cloud request).
  void heard(uint32_t peer, Nanos now);
  // This robot wrote a loop (the caller's handle `id`, larger than any before) between keyframes a and b:
  // accepted, or withdrawing the accepted one of that pair (which is then never written again: a copy
  // arriving after the withdrawal would revive it). Returns the handle of the loop forgotten to make
  // room, if any: the caller can let go of its message.
  std::optional<uint64_t> published(uint64_t id, uint32_t robot_a, uint32_t keyframe_a, uint32_t robot_b,
                                    uint32_t keyframe_b, bool withdrawal, Nanos now);
  // The loops to write again now (ascending handles, each once per call).
  std::vector<uint64_t> due(Nanos now);

  const PeerReachStats& stats() const { return stats_; }

 private:
  struct Written {
    uint64_t id;
    uint32_t robot_a, keyframe_a, robot_b, keyframe_b;
    bool withdrawal;
    Nanos at;
    bool withdrawn = false;  // an accepted loop withdrawn since
  };
  struct Catchup {
    Nanos since;  // loops written from here on involving the peer
    Nanos at;     // when to write them
  };
  uint32_t me_;
  PeerReachParams p_;
  std::map<uint32_t, Nanos> last_heard_;
  std::map<uint32_t, Catchup> catchup_;
  std::deque<Written> written_;  // in writing order
  PeerReachStats stats_;
};

}  // namespace cdc::loops
