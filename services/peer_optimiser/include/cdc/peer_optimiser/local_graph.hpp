// What one robot knows of the swarm's pose graph: its own keyframes (odometry), every loop touching
// it (each once, withdrawn ones kept as withdrawn), the inter-robot loops between other robots its
// peers relay (for the coarse step), and its peers' separator poses as last received.
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/peer_optimiser/peer_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <tuple>
#include <utility>
#include <vector>

namespace cdc::peer {

class LocalGraph {
 public:
  explicit LocalGraph(uint32_t robot) : robot_(robot) {}

  // Each returns false for a record already held (a keyframe by id, a loop by sender, incarnation
  // and seq), which changes nothing.
  bool add_keyframe(const OwnKeyframe& kf);
  bool add_loop(const LoopRecord& loop);
  // An inter-robot loop between two other robots, relayed by a peer. Returns false for one held
  // already and for a loop touching this robot (those come from the loop closures themselves).
  bool add_group_loop(const LoopRecord& loop);
  void on_separator(uint32_t from, const KeyframePoses& poses);
  // What a peer says of its coarse step: how many inter-robot loops it has (inter_robot_loops_of
  // itself) and whether it runs the step.
  void on_coarse_view(uint32_t from, uint32_t loops, bool coarse_step) { coarse_views_[from] = {loops, coarse_step}; }
  // How many of the inter-robot loops held touch `robot`.
  uint32_t inter_robot_loops_of(uint32_t robot) const;
  // Whether `robot` solves the same coarse step as this one: it runs it and this robot holds every
  // inter-robot loop it has (as many as it said it has). Always true for this robot itself.
  bool shares_coarse_step_with(uint32_t robot) const;

  uint32_t robot() const noexcept { return robot_; }
  const std::map<uint32_t, OwnKeyframe>& keyframes() const noexcept { return keyframes_; }
  const std::vector<LoopRecord>& loops() const noexcept { return loops_; }
  const std::vector<LoopRecord>& group_loops() const noexcept { return group_loops_; }
  const std::map<Key, Eigen::Isometry3d>& separators() const noexcept { return separators_; }
  std::optional<uint32_t> newest_id() const;

  // Per peer, the own keyframes its (not withdrawn) loops with this robot touch: the separator
  // poses that peer needs.
  std::map<uint32_t, std::set<uint32_t>> separator_ids() const;
  // The robots its group is known to hold: those the inter-robot loops known (its own and the
  // relayed ones) link to this robot, directly or through others, without this robot.
  std::set<uint32_t> group() const;
  // Every inter-robot loop known (own and relayed) that holds: not withdrawn, and no withdrawal of
  // a loop between the same two keyframes is held.
  std::vector<const LoopRecord*> inter_robot_loops() const;
  // Per robot of the group, every own keyframe an inter-robot loop touches (what the coarse step
  // of every robot of the group needs from this one).
  std::map<uint32_t, std::set<uint32_t>> group_separator_ids() const;
  // Per robot of the group, the own inter-robot loops to relay to it: those this robot is the lower
  // end of and the robot is no end of (withdrawals included).
  std::map<uint32_t, std::vector<LoopRecord>> loops_to_relay() const;
  // True when no loop ties this robot to a lower robot: its odometry frame is its group's frame.
  bool lowest_in_group() const;
  // Odometry factors between consecutive own keyframes, appended to g.
  void add_odometry_factors(graph::PoseGraph& g) const;
  // T_world_robot of a solution, as the central defines it: the rigid fit of its poses to this
  // robot's odometry keyframes (paper eq. 1-2). None when the fit is degenerate.
  std::optional<Eigen::Isometry3d> world_transform_of(const KeyframePoses& poses) const;
  // The whole graph: own keyframes at `estimate` where it has them (else their odometry) with their
  // odometry factors, the separator poses, and every loop whose both ends are there.
  graph::PoseGraph graph(const std::map<uint32_t, Eigen::Isometry3d>& estimate) const;

 private:
  uint32_t robot_;
  std::map<uint32_t, OwnKeyframe> keyframes_;
  std::vector<LoopRecord> loops_;
  std::vector<LoopRecord> group_loops_;                          // relayed: between two other robots
  std::set<std::tuple<uint32_t, uint32_t, uint32_t>> loop_ids_;  // sender, incarnation, seq
  std::map<Key, Eigen::Isometry3d> separators_;                  // peers' keyframes, T_world
  std::map<uint32_t, std::pair<uint32_t, bool>> coarse_views_;   // peer -> its loops, runs the coarse step
};

}  // namespace cdc::peer
