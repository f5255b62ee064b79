// Which separator poses go to which peer each round. A peer gets the poses of the own keyframes its
// loops touch, only while it is DISTRIBUTED (a CENTRALIZED peer solves with the central's poses) and
// within `peer_range_m`; a pose goes again only once it has moved `separator_min_change_m` or turned
// `separator_min_change_rad` since it was last sent there, and all of them every `separator_refresh`.
// A peer that may have missed some (out of range, CENTRALIZED, or its reader matched anew) gets all
// of them at its next round. Loops relayed for the peer's coarse step go with them, each once (again
// after such a miss).
#pragma once

#include "cdc/peer_optimiser/peer_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <tuple>
#include <vector>

namespace cdc::peer {

// What a robot says of its coarse step (SeparatorOut::inter_robot_loops, coarse_step).
struct CoarseView {
  uint32_t inter_robot_loops = 0;
  bool coarse_step = false;
  bool operator==(const CoarseView&) const = default;
};

class SeparatorExchange {
 public:
  explicit SeparatorExchange(const PeerConfig& config) : config_(config) {}

  // The back-end mode a peer reports; a peer not heard of yet counts as DISTRIBUTED.
  void on_peer_mode(uint32_t robot, Mode mode) { peer_modes_[robot] = mode; }
  void on_peer_position(uint32_t robot, const Eigen::Vector3d& p) { peer_positions_[robot] = p; }
  // The peer may have missed separator poses sent to it: its next round sends it all of them.
  void resend_to(uint32_t peer);

  // One round's separator poses. `wanted`: per peer, the own keyframes its loops touch; `own`: the
  // own keyframes' poses in W; `world_pose`: this robot's current pose in W (none: every peer
  // counts as in range); `relay`: per peer, the loops to relay to it; `view`: how many inter-robot
  // loops this robot has and whether it runs the coarse step, sent with every message and on its own
  // when it changed.
  std::vector<SeparatorOut> round(Nanos now, const std::map<uint32_t, std::set<uint32_t>>& wanted,
                                  const std::map<uint32_t, Eigen::Isometry3d>& own,
                                  const std::optional<Eigen::Isometry3d>& world_pose,
                                  const std::map<uint32_t, std::vector<LoopRecord>>& relay = {}, CoarseView view = {});

 private:
  bool uses_separators(uint32_t peer, const std::optional<Eigen::Isometry3d>& world_pose) const;
  bool moved(const Eigen::Isometry3d& before, const Eigen::Isometry3d& now) const;
  SeparatorOut poses_for(uint32_t peer, Nanos now, const std::set<uint32_t>& ids,
                         const std::map<uint32_t, Eigen::Isometry3d>& own);
  std::vector<LoopRecord> loops_for(uint32_t peer, const std::vector<LoopRecord>& loops);

  PeerConfig config_;
  std::map<uint32_t, Eigen::Vector3d> peer_positions_;
  std::map<uint32_t, Mode> peer_modes_;
  std::map<uint32_t, std::map<uint32_t, Eigen::Isometry3d>> sent_;                  // peer -> own keyframe -> pose sent
  std::map<uint32_t, Nanos> refreshed_;                                             // peer -> last full send
  std::map<uint32_t, std::set<std::tuple<uint32_t, uint32_t, uint32_t>>> relayed_;  // peer -> loops sent
  std::map<uint32_t, CoarseView> view_sent_;                                        // peer -> view sent
};

}  // namespace cdc::peer
