// Which verified loops to publish. Every robot's odometry goes into one pose graph: a robot whose
// keyframes are held here with its own odometry, others chained through their descriptors' pose
// hints with a nominal noise model (PCM needs both robots' odometry). A same-robot loop is accepted
// when it agrees with the robot's odometry between its two keyframes. Inter-robot loops are decided
// per robot pair by PCM (pairwise consistency maximisation) over the pair's proposed loops: a
// consistent set is published once it has min_inter_support loops resting on at least two keyframes
// of each robot; a published loop that leaves the set is withdrawn. Synchronous, no I/O.
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/loop_closure/loop_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <set>
#include <utility>
#include <vector>

namespace cdc::loops {

struct PcmStats {
  uint64_t intra_accepted = 0, intra_inconsistent = 0, inter_proposed = 0, inter_accepted = 0, withdrawn = 0;
};

class PairwiseConsistency {
 public:
  explicit PairwiseConsistency(const LoopParams& params) : p_(params) {}

  // A keyframe held here: its odometry from the robot's previous keyframe (none for keyframe 0).
  void add_keyframe_odometry(uint32_t robot, uint32_t id, const Eigen::Isometry3d& T_prev,
                             const graph::Matrix6d& information);
  // A descriptor's pose hint (T_odom_keyframe): chains a robot without keyframes held here from its
  // latest earlier hint.
  void add_pose_hint(uint32_t robot, uint32_t id, const Eigen::Isometry3d& pose_hint);
  // A verified loop: what is published or withdrawn because of it, in order.
  std::vector<LoopOut> add_loop(const LoopOut& loop);

  const PcmStats& stats() const noexcept { return stats_; }

 private:
  using RobotPair = std::pair<uint32_t, uint32_t>;  // lower robot first
  void add_odometry(uint32_t robot, uint32_t from, uint32_t to, const Eigen::Isometry3d& T,
                    const graph::Matrix6d& info);
  std::vector<LoopOut> add_intra(const LoopOut& loop);
  std::vector<LoopOut> add_inter(const LoopOut& loop);
  // The pair's loops PCM keeps as a set large and broad enough to publish (factor ids).
  std::set<size_t> publishable(const RobotPair& pair);
  // Publishes what joined the set and withdraws what left it.
  std::vector<LoopOut> publish(const RobotPair& pair, const std::set<size_t>& accepted);

  LoopParams p_;
  std::set<uint32_t> data_robots_;                                        // robots with odometry from keyframes
  std::map<uint32_t, std::pair<uint32_t, Eigen::Isometry3d>> last_hint_;  // robot -> (id, pose hint)
  graph::PoseGraph graph_;                                                // every robot's odometry + loops
  std::map<RobotPair, std::vector<size_t>> inter_;                        // robot pair -> factor ids
  std::map<size_t, LoopOut> proposed_;                                    // factor id -> loop
  std::set<size_t> published_;                                            // factor ids accepted and published
  PcmStats stats_;
};

}  // namespace cdc::loops
