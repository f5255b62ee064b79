// The robot's own estimate in DISTRIBUTED mode (paper III-A-2): rounds that optimise its keyframes,
// its odometry and the loops touching it, with its peers' separator poses held fixed. Every robot
// solves at once (block Jacobi), so each round moves the own keyframes only `relaxation` of the way
// to its solution. Without the central's estimate a round starts with the coarse step of the
// two-stage solve (graph/distributed_robot.hpp): one rigid move per robot of the group, which
// every robot solves alike from the same loops and poses, so that the rounds converge in shape and
// not only in cost. Its gauge is the group's lowest robot: it holds still in the coarse step, and
// after its own block solve (with no keyframe pinned) it moves rigidly back so that its first
// keyframe is at its odometry pose. A robot of the group is in the group's frame once a coarse step
// has placed it.
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/peer_optimiser/local_graph.hpp"
#include "cdc/peer_optimiser/peer_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <set>

namespace cdc::peer {

class DistributedEstimate {
 public:
  explicit DistributedEstimate(const PeerConfig& config) : config_(config) {}

  // Forgets the estimate: the next round starts again from the central's last one.
  void clear() { estimate_.clear(); }
  // A new own keyframe follows its predecessor's estimate by its odometry, when that has one.
  void extend(const OwnKeyframe& kf);
  // Gives every own keyframe without an estimate one: the central's pose when `central` has it,
  // else its predecessor's estimate times its odometry, else T_world_robot times its odometry pose.
  void seed(const LocalGraph& known, const KeyframePoses& central,
            const std::optional<Eigen::Isometry3d>& T_world_robot);
  // One round: seeds, places the robot in its group's frame through a peer if it has no other
  // anchor yet, solves and relaxes. Returns T_world_robot of the new estimate; none without
  // keyframes or factors, or for a degenerate fit. `central`: the central's last poses (may be empty).
  std::optional<Eigen::Isometry3d> round(const LocalGraph& known, const KeyframePoses& central,
                                         const std::optional<Eigen::Isometry3d>& T_world_robot);

  const std::map<uint32_t, Eigen::Isometry3d>& poses() const noexcept { return estimate_; }
  // The estimate has been moved into the group's frame through a peer's separator pose, or by a
  // coarse step held by a lower robot.
  bool placed_by_peers() const noexcept { return placed_by_peers_; }
  uint64_t rounds() const noexcept { return rounds_; }
  uint64_t coarse_steps() const noexcept { return coarse_steps_; }
  // Own loops the last round's GNC held out (of a round whose solve converged).
  size_t own_loops_held_out() const noexcept { return own_loops_held_out_; }

 private:
  // A round's problem: the graph to solve and the separator poses held fixed in it.
  struct Problem {
    graph::PoseGraph graph;
    std::set<Key> fixed;
    bool lowest = true;  // no separator of a lower robot in it: this robot is the lowest of its group
  };
  using Separators = std::map<Key, Eigen::Isometry3d>;
  // What a coarse step did: the group's gauge robot, when it ran.
  struct Coarse {
    std::optional<uint32_t> gauge;
  };

  bool place_through_peers(const LocalGraph& known);
  Coarse coarse_step(const LocalGraph& known, Separators& separators);
  Problem problem(const LocalGraph& known, const Separators& separators) const;
  void anchor(Problem& p, const LocalGraph& known, const KeyframePoses& central, const Coarse& coarse) const;
  void solve(Problem& p);
  void relax_towards(const graph::PoseGraph& solution);
  void hold_gauge(const LocalGraph& known);

  PeerConfig config_;
  std::map<uint32_t, Eigen::Isometry3d> estimate_;  // own keyframes, T_world
  bool placed_by_peers_ = false;
  uint64_t rounds_ = 0;
  uint64_t coarse_steps_ = 0;
  size_t own_loops_held_out_ = 0;
};

}  // namespace cdc::peer
