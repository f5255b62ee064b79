// The peer optimiser's synchronous core: the robot's back-end agent. It decides the mode (RTDOS),
// relays the central's estimate in CENTRALIZED mode, optimises its own graph with its peers'
// separator poses in DISTRIBUTED mode, limits every correction it publishes with the paper's
// adaptive fusion (eq. 8-14), and tells the node what to re-send to a central that lacks it.
#pragma once

#include "cdc/geometry/fusion.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/peer_optimiser/rtdos.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <vector>

namespace cdc::peer {

using graph::Key;
using graph::Matrix6d;

struct PeerConfig {
  uint32_t robot = 0;
  uint32_t robot_count = 3;
  RtdosParams rtdos;
  geometry::FusionThresholds fusion;
  double peer_range_m = 1e9;               // separators go only to peers closer than this
  Nanos round_period{std::chrono::milliseconds(200)};   // distributed optimisation rounds
  Nanos resend_grace{std::chrono::milliseconds(1500)};  // unacknowledged this long: re-send
  Nanos resend_period{std::chrono::milliseconds(500)};
  int distributed_iterations = 5;
  // Each round moves the own keyframes this fraction of the way to the block's solution (in each
  // pose's tangent space). Every robot solves at once with its peers' last separators held fixed
  // (block Jacobi); taken whole (1.0), two coupled robots each jump onto the other's old poses and
  // the pair oscillates instead of settling: replaying session 19's KITTI graphs (cdc-peer-replay) the
  // joint cost stayed 1.5-40 times the optimum, 30 s after the last keyframe. Damped it reaches it.
  double relaxation = 0.7;
  // A separator pose goes to a peer again only once it has moved this far since it was last sent
  // there (the rounds settle, and most poses stop moving). The topic is reliable, so a peer misses
  // one only when it was out of reach long enough to be unmatched (or restarted): the node then
  // calls resend_separators_to() when the peer's reader matches again. Every `separator_refresh`
  // the peer gets all of them anyway, a safety net.
  double separator_min_change_m = 0.001;
  double separator_min_change_rad = 0.01 * M_PI / 180.0;
  Nanos separator_refresh{std::chrono::seconds(30)};
  // Loops through one keyframe share its cloud's errors: each loop's information is divided by the
  // most loops either of its keyframes takes part in (graph::share_loop_information).
  bool share_loop_information = true;
  // Keyframes (and loops) re-sent per step at most: a rejoin's backlog (hundreds of keyframes of
  // ~110 KB) written at once blocked the node's loop for seconds under flow control.
  size_t max_resend_per_step = 50;
};

struct OwnKeyframe {
  uint32_t id = 0;
  uint32_t incarnation = 0;
  Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_prev = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();
};

struct LoopRecord {
  uint32_t sender = 0, sender_incarnation = 0, seq = 0;
  uint32_t robot_a = 0, keyframe_a = 0, robot_b = 0, keyframe_b = 0;
  bool withdrawn = false;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();
};

struct CentralResult {
  uint32_t central_incarnation = 0;
  uint64_t version = 0;
  Eigen::Isometry3d T_world_robot = Eigen::Isometry3d::Identity();
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;  // own keyframes, T_world_keyframe
  // The central has not placed the robot in its graph yet and returns the robot's own hint (its
  // T_world_robot times the odometry): W is known, but there is no correction in it to relay.
  bool from_hint = false;
};

struct AckIn {
  uint32_t central_incarnation = 0;
  uint32_t robot_incarnation = 0;
  int64_t keyframe = -1;
  int64_t loop_seq = -1;
};

struct Correction {
  Eigen::Isometry3d T_world_robot;            // limited by the fusion thresholds
  double lambda = 1.0;                        // the fusion factor applied
  bool from_central = true;
  // Current estimate of own keyframes, in the frame of T_world_robot above (the solution moved with it).
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;
};

struct SeparatorOut {
  uint32_t target = 0;
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;  // own keyframes the target's loops touch
};

struct StepOutput {
  std::optional<Transition> transition;
  std::optional<Correction> correction;
  std::vector<SeparatorOut> separators;
  std::optional<Eigen::Isometry3d> world_transform;  // own estimate for the central (on rejoin)
  std::vector<uint32_t> resend_keyframes;
  std::vector<uint32_t> resend_loops;                 // own loop seqs
};

// Every keyframe in W (keyframe id -> T_world_keyframe): as in `corrected` where it is there, else
// placed by its odometry pose T_odom relative to the nearest corrected keyframe before it (the
// first corrected one for keyframes older than all of them). Without any correction: T_odom.
std::map<uint32_t, Eigen::Isometry3d> complete_world_poses(const std::map<uint32_t, Eigen::Isometry3d>& T_odom,
                                                           const std::map<uint32_t, Eigen::Isometry3d>& corrected);

class PeerCore {
 public:
  explicit PeerCore(const PeerConfig& config, Nanos start = Nanos{0});

  void add_keyframe(const OwnKeyframe& kf, Nanos now);
  void add_loop(const LoopRecord& loop, Nanos now);  // any loop touching this robot
  void on_central_result(const CentralResult& r);
  void on_ack(const AckIn& a);
  void on_separator(uint32_t from, const std::vector<std::pair<uint32_t, Eigen::Isometry3d>>& poses);
  void on_central_position(const Eigen::Vector3d& p) { central_position_ = p; }
  void on_peer_position(uint32_t robot, const Eigen::Vector3d& p) { peer_positions_[robot] = p; }
  // The back-end mode a peer reports. A CENTRALIZED peer solves with the central's poses, not with
  // separators: it gets none, and all of them at the first round after it reports DISTRIBUTED.
  // A peer not heard of yet gets them.
  void on_peer_mode(uint32_t robot, Mode mode) { peer_modes_[robot] = mode; }
  // The peer may have missed separators sent to it (its reader matched anew): the next round sends
  // it all of them.
  void resend_separators_to(uint32_t peer) {
    separators_sent_.erase(peer);
    separators_refreshed_.erase(peer);
  }

  // One tick of the agent.
  StepOutput step(Nanos now, bool central_alive);

  Mode mode() const noexcept { return rtdos_.mode(); }
  const Rtdos& rtdos() const noexcept { return rtdos_; }
  bool world_valid() const noexcept { return published_.has_value(); }
  // Current pose in W from the published correction and the latest odometry.
  std::optional<Eigen::Isometry3d> world_pose() const;
  std::optional<double> distance_to_central() const;
  int64_t last_keyframe_id() const;
  // The highest keyframe id up to which the current central has acknowledged every keyframe (-1: none).
  int64_t central_acknowledged_keyframe() const noexcept { return ack_.keyframe; }
  uint64_t distributed_rounds() const noexcept { return rounds_; }
  // What this robot knows, as a pose graph: its keyframes (at the distributed estimate, else their
  // odometry) with their odometry factors, every loop touching it, and its peers' separator poses as
  // received. The union of every robot's graph is the swarm's graph (cdc-peer-replay merges them).
  graph::PoseGraph graph() const;

 private:
  std::optional<Eigen::Isometry3d> distributed_round();
  // T_world_robot of a solution: the rigid fit of its poses to this robot's odometry keyframes.
  std::optional<Eigen::Isometry3d> solution_world_transform(
      const std::vector<std::pair<uint32_t, Eigen::Isometry3d>>& poses) const;
  void ensure_initial_values();
  bool lowest_in_group() const;

  PeerConfig config_;
  Rtdos rtdos_;
  std::map<uint32_t, OwnKeyframe> keyframes_;
  std::map<uint32_t, Nanos> keyframe_seen_;
  std::vector<LoopRecord> loops_;
  std::map<uint32_t, Nanos> own_loop_seen_;           // own loops by seq
  std::set<std::tuple<uint32_t, uint32_t, uint32_t>> loop_ids_;
  std::optional<CentralResult> central_;
  uint32_t central_incarnation_ = 0;
  AckIn ack_;
  std::map<Key, Eigen::Isometry3d> separators_;        // peers' keyframes, T_world
  std::map<uint32_t, std::map<uint32_t, Eigen::Isometry3d>> separators_sent_;  // target -> own keyframe -> pose sent
  std::map<uint32_t, Nanos> separators_refreshed_;                               // target -> last full send
  std::map<uint32_t, Eigen::Isometry3d> estimate_;     // own keyframes, T_world (distributed)
  std::optional<Eigen::Isometry3d> target_;            // T_world_robot the back-end believes
  std::optional<Eigen::Isometry3d> published_;         // what the front-end has been told
  std::optional<Eigen::Vector3d> central_position_;
  std::map<uint32_t, Eigen::Vector3d> peer_positions_;
  std::map<uint32_t, Mode> peer_modes_;
  Nanos last_round_{0};
  Nanos last_resend_{0};
  bool rejoining_ = false;
  // Set on joining the central: the newest own keyframe then. The central's results are relayed
  // only once one holds it; until then the corrections stay the distributed estimate's.
  std::optional<uint32_t> frontier_;
  std::optional<uint32_t> relayed_newest_;  // newest own keyframe in a central result relayed (this central incarnation)
  bool placed_by_peers_ = false;  // estimate_ moved into the group's frame through a separator
  uint64_t rounds_ = 0;
};

}  // namespace cdc::peer
