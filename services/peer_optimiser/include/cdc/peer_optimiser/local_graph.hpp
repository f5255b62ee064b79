// What one robot knows of the swarm's pose graph: its own keyframes (odometry), every loop touching
// it (each once, withdrawn ones kept as withdrawn), and its peers' separator poses as last received.
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/peer_optimiser/peer_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <tuple>
#include <vector>

namespace cdc::peer {

class LocalGraph {
 public:
  explicit LocalGraph(uint32_t robot) : robot_(robot) {}

  // Each returns false for a record already held (a keyframe by id, a loop by sender, incarnation
  // and seq), which changes nothing.
  bool add_keyframe(const OwnKeyframe& kf);
  bool add_loop(const LoopRecord& loop);
  void on_separator(uint32_t from, const KeyframePoses& poses);

  uint32_t robot() const noexcept { return robot_; }
  const std::map<uint32_t, OwnKeyframe>& keyframes() const noexcept { return keyframes_; }
  const std::vector<LoopRecord>& loops() const noexcept { return loops_; }
  const std::map<Key, Eigen::Isometry3d>& separators() const noexcept { return separators_; }
  std::optional<uint32_t> newest_id() const;

  // Per peer, the own keyframes its (not withdrawn) loops with this robot touch: the separator
  // poses that peer needs.
  std::map<uint32_t, std::set<uint32_t>> separator_ids() const;
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
  std::set<std::tuple<uint32_t, uint32_t, uint32_t>> loop_ids_;  // sender, incarnation, seq
  std::map<Key, Eigen::Isometry3d> separators_;                  // peers' keyframes, T_world
};

}  // namespace cdc::peer
