// The peer optimiser's synchronous core: the robot's back-end agent. It decides the mode (RTDOS),
// relays the central's estimate in CENTRALIZED mode, optimises its own graph with its peers'
// separator poses in DISTRIBUTED mode, limits every correction it publishes with the paper's
// adaptive fusion (eq. 8-14), and tells the node what to re-send to a central that lacks it.
#pragma once

#include "cdc/geometry/trajectory.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/peer_optimiser/central_backlog.hpp"
#include "cdc/peer_optimiser/central_relay.hpp"
#include "cdc/peer_optimiser/distributed_estimate.hpp"
#include "cdc/peer_optimiser/local_graph.hpp"
#include "cdc/peer_optimiser/peer_types.hpp"
#include "cdc/peer_optimiser/rtdos.hpp"
#include "cdc/peer_optimiser/separator_exchange.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <vector>

namespace cdc::peer {

// Every keyframe in W (keyframe id -> T_world_keyframe): as in `corrected` where it is there, else
// placed by its odometry pose T_odom relative to the nearest corrected keyframe before it (the
// first corrected one for keyframes older than all of them). Without any correction: T_odom.
std::map<uint32_t, Eigen::Isometry3d> complete_world_poses(const std::map<uint32_t, Eigen::Isometry3d>& T_odom,
                                                           const std::map<uint32_t, Eigen::Isometry3d>& corrected);

// Keyframes offered to the core that it did not take.
struct KeyframeCounters {
  uint64_t duplicate = 0;  // held already
  uint64_t refused = 0;    // conflicting with what is held
};

// What the rounds sent to peers: separator poses and relayed loops, counted when given out.
struct SeparatorTraffic {
  uint64_t poses = 0;
  uint64_t loops = 0;
};

class PeerCore {
 public:
  explicit PeerCore(const PeerConfig& config, Nanos start = Nanos{0});

  // The core is the one owner of the robot's keyframes: the node keeps a keyframe's cloud only when
  // this accepts it. A robot's keyframes form one sequence (one incarnation, ids 0, 1, 2, ... ; a
  // restarted front-end continues it, see idl/README.md): a keyframe whose id is held with another
  // incarnation or stamp, or of another incarnation than the sequence's, is refused with the reason.
  KeyframeAdmission add_keyframe(const OwnKeyframe& kf, Nanos now);
  void add_loop(const LoopRecord& loop, Nanos now);  // any loop touching this robot
  void on_central_result(const CentralResult& r);
  void on_ack(const AckIn& a);
  // A peer's separator poses, and the inter-robot loops between other robots it relays (for the
  // coarse step; loops touching this robot come from the loop closures themselves).
  void on_separator(uint32_t from, const KeyframePoses& poses) { known_.on_separator(from, poses); }
  // What a peer's step gave out for this robot (`message.target`): separator poses, relayed loops,
  // and how many inter-robot loops the peer holds.
  void on_separator(uint32_t from, const SeparatorOut& message);
  // The central's position in W; nullopt when the central knows no world yet (a restarted one before
  // its host robot's poses reach it): the distance to it is then unknown, not measured from the origin.
  void on_central_position(const std::optional<Eigen::Vector3d>& p) { central_position_ = p; }
  void on_peer_position(uint32_t robot, const Eigen::Vector3d& p) { separators_.on_peer_position(robot, p); }
  // The back-end mode a peer reports. A CENTRALIZED peer solves with the central's poses, not with
  // separators: it gets none, and all of them at the first round after it reports DISTRIBUTED.
  // A peer not heard of yet gets them.
  void on_peer_mode(uint32_t robot, Mode mode) { separators_.on_peer_mode(robot, mode); }
  // The peer may have missed separators sent to it (its reader matched anew): the next round sends
  // it all of them.
  void resend_separators_to(uint32_t peer) { separators_.resend_to(peer); }

  // One tick of the agent.
  StepOutput step(Nanos now, bool central_alive);

  // Whether an own keyframe made now goes on to the central: only while CENTRALIZED. A DISTRIBUTED
  // robot withholds it; it reaches the central with the backlog re-sent on rejoining.
  bool forwards_keyframes() const noexcept { return mode() == Mode::kCentralized; }

  Mode mode() const noexcept { return rtdos_.mode(); }
  const Rtdos& rtdos() const noexcept { return rtdos_; }
  bool world_valid() const noexcept { return published_.has_value(); }
  // Current pose in W from the published correction and the latest odometry.
  std::optional<Eigen::Isometry3d> world_pose() const;
  std::optional<double> distance_to_central() const;
  int64_t last_keyframe_id() const;
  // The newest keyframe held (where a restarted front-end continues), nullptr before the first.
  const OwnKeyframe* newest_keyframe() const;
  const OwnKeyframe* keyframe(uint32_t id) const;
  size_t keyframes_held() const noexcept { return known_.keyframes().size(); }
  const KeyframeCounters& keyframe_counters() const noexcept { return keyframe_counters_; }
  // Every keyframe in W at its stamp, in id order: as the published corrections last placed it,
  // else by its odometry relative to a corrected one (complete_world_poses).
  geometry::Trajectory world_trajectory() const;
  // The highest keyframe id up to which the current central has acknowledged every keyframe (-1: none).
  int64_t central_acknowledged_keyframe() const noexcept { return backlog_.acknowledged_keyframe(); }
  uint64_t distributed_rounds() const noexcept { return distributed_.rounds(); }
  uint64_t coarse_steps() const noexcept { return distributed_.coarse_steps(); }
  size_t own_loops_held_out() const noexcept { return distributed_.own_loops_held_out(); }
  const SeparatorTraffic& separator_traffic() const noexcept { return traffic_; }
  // What this robot knows, as a pose graph: its keyframes (at the distributed estimate, else their
  // odometry) with their odometry factors, every loop touching it, and its peers' separator poses as
  // received. The union of every robot's graph is the swarm's graph (cdc-peer-replay merges them).
  graph::PoseGraph graph() const;

 private:
  void enter_distributed(StepOutput& out);
  void enter_centralized(StepOutput& out);
  void follow_distributed_round();
  bool in_group_frame() const;
  std::vector<SeparatorOut> separators_due(Nanos now);
  Correction next_correction(bool from_central);
  std::optional<std::string> conflict(const OwnKeyframe& kf) const;

  PeerConfig config_;
  Rtdos rtdos_;
  LocalGraph known_;
  CentralRelay central_;
  CentralBacklog backlog_;
  SeparatorExchange separators_;
  DistributedEstimate distributed_;
  uint32_t central_incarnation_ = 0;
  std::optional<Eigen::Isometry3d> target_;     // T_world_robot the back-end believes
  std::optional<Eigen::Isometry3d> published_;  // what the front-end has been told
  std::optional<Eigen::Vector3d> central_position_;
  Nanos last_round_{0};
  std::map<uint32_t, Eigen::Isometry3d> corrected_;  // T_world_keyframe as last published
  KeyframeCounters keyframe_counters_;
  SeparatorTraffic traffic_;
};

}  // namespace cdc::peer
