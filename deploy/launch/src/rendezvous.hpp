// The end of a mission with a final rendezvous: after the last sweep every robot comes back in range,
// and the run ends once every robot has been CENTRALIZED, with all its keyframes held by the central,
// and every loop-closure service has caught up (the descriptors of peers' keyframes made out of range
// searched, the clouds their candidates need received), both for `settle` (a robot cut just before the
// last sweep still reads CENTRALIZED until the central's lease lapses); or at the latest after `limit`.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <vector>

namespace cdc::launch {

class Rendezvous {
 public:
  using Clock = std::chrono::steady_clock;

  Rendezvous(Clock::time_point start, Clock::duration settle, Clock::duration limit)
      : start_(start), settle_(settle), limit_(limit) {}

  // One look at the swarm at `now`: the robots not (yet) rejoined and those whose loop closure is busy.
  // True once the rendezvous is over; the figures below then describe it.
  bool update(std::vector<uint32_t> not_rejoined, std::vector<uint32_t> busy, Clock::time_point now);

  // How long the rejoins took (until every robot was in, or until the end when one never was) [s].
  double waited_s() const;
  // When every loop closure had caught up, if they all had [s after the start].
  std::optional<double> caught_up_s() const;
  const std::vector<uint32_t>& not_rejoined() const { return not_rejoined_; }
  const std::vector<uint32_t>& loop_closure_busy() const { return busy_; }

 private:
  Clock::time_point start_;
  Clock::duration settle_, limit_;
  bool all_rejoined_ = false;  // every robot CENTRALIZED since all_rejoined_at_
  Clock::time_point all_rejoined_at_{};
  bool caught_up_ = false;  // every loop closure caught up since caught_up_at_
  Clock::time_point caught_up_at_{};
  Clock::time_point ended_at_{};
  std::vector<uint32_t> not_rejoined_, busy_;
};

}  // namespace cdc::launch
