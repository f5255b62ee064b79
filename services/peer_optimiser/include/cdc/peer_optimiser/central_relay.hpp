// The central's last result for this robot, and whether it is current enough to relay to the
// front-end. After a rejoin the central's estimate of the robot is current only once it holds every
// keyframe made up to the rejoin (the frontier): until then its last result is from before the cut,
// or from a graph still taking in the re-sent backlog, and relaying it would pull the front-end back
// to where the robot was then. A result holding fewer own keyframes than one already relayed (the
// central placing the robot anew, with a gap in the backlog it fills in order) moves the frontier
// back out to the newest relayed keyframe. A placement from the robot's own hint holds every
// keyframe but no correction: it is never relayed and never reaches the frontier.
#pragma once

#include "cdc/peer_optimiser/peer_types.hpp"

#include <cstdint>
#include <optional>

namespace cdc::peer {

class CentralRelay {
 public:
  void on_result(const CentralResult& r) { last_ = r; }
  // A new central incarnation: nothing of its results has been relayed yet.
  void forget_relayed() { relayed_newest_.reset(); }
  // The robot rejoins the central, its newest keyframe then `newest_own` (none: no keyframe yet).
  void on_rejoin(std::optional<uint32_t> newest_own) { frontier_ = newest_own; }
  // Whether the last result is to be relayed now; called once per step, it moves the frontier.
  bool update();

  const std::optional<CentralResult>& last() const noexcept { return last_; }
  // The last result's poses (empty without one).
  const KeyframePoses& poses() const noexcept { return last_ ? last_->poses : kNone; }
  // The central has given own keyframe poses, so W is known.
  bool has_poses() const noexcept { return last_ && !last_->poses.empty(); }

 private:
  // The newest own keyframe of the last result, unless that is from the robot's hint.
  std::optional<uint32_t> placed_newest() const;

  static inline const KeyframePoses kNone{};
  std::optional<CentralResult> last_;
  std::optional<uint32_t> frontier_;        // relay only a result holding this keyframe
  std::optional<uint32_t> relayed_newest_;  // newest own keyframe of a result relayed (this central incarnation)
};

}  // namespace cdc::peer
