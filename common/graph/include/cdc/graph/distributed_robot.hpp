// One robot's share of the two-stage distributed pose-graph solve (in the spirit of distributed
// Gauss-Seidel, Choudhary et al. IJRR 2017). The robot holds its own poses and every factor that
// touches them; per round it takes the separator estimates its neighbours sent (the poses at the
// far end of its inter-robot factors), solves for its own block with those held constant, and hands
// back its own separator estimates. Three stages, each a sequence of such rounds:
//  1. rotations: the chordal relaxation  sum kappa ||M_b - M_a R_ab||_F^2  (linear in the 3x3
//     matrices M), solved by block successive over-relaxation; then each M is projected onto SO(3);
//  2. translations given those rotations:  sum tau ||t_b - t_a - R_a t_ab||^2  (linear), the same way;
//  3. the full nonlinear objective: block solves with separator poses, each round followed by a
//     coarse step (coarse_corrections) that moves every robot rigidly.
// Block solves alone shrink the errors that span several robots (a slow bend or turn of the whole
// map) by a few percent per round: each robot's poses are held by its neighbours' as much as by its
// own odometry. Such errors are nearly rigid moves of each robot, which the coarse step, a problem
// of 6 unknowns per robot, removes at once. A neighbour value not received yet leaves its factors
// out of the round (the first round of a stage acts as a placement of robots next to those already
// heard from).
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/graph/solver.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <vector>

namespace cdc::graph {

// Separator estimates as they travel between robots, by key.
using SeparatorRotations = std::map<Key, Eigen::Matrix3d>;     // stage 1: relaxed rotations M (not yet on SO(3))
using SeparatorTranslations = std::map<Key, Eigen::Vector3d>;  // stage 2: positions [m]
using SeparatorPoses = std::map<Key, Eigen::Isometry3d>;       // stage 3: T_world_key

// Bytes of one separator estimate on the wire: a 4-byte keyframe id and floats.
inline constexpr uint64_t kSeparatorRotationBytes = 4 + 9 * 4;
inline constexpr uint64_t kSeparatorTranslationBytes = 4 + 3 * 4;
// Bytes of one factor on the wire: two 4-byte keyframe ids, the measurement in 7 floats and the
// 21 upper-triangular floats of its information.
inline constexpr uint64_t kFactorBytes = 2 * 4 + 7 * 4 + 21 * 4;

namespace detail {
// One term  w ||x_j - A x_i - c||^2  of a linear block problem over (d x 3) blocks x (stage 1:
// x = M^T, d = 3; stage 2: x = t^T, d = 1); a prior has no i:  w ||x_j - c||^2.
struct LinearTerm {
  std::optional<Key> i;
  Key j = 0;
  Eigen::MatrixXd A;
  Eigen::MatrixXd c;
  double w = 0;
};
}  // namespace detail

// The corrections of the coarse step: one rigid move per robot, and one of its own per pinned pose
// (a pose with a prior; the gauge pose is pinned too and stays put).
struct CoarseCorrections {
  std::map<uint32_t, Eigen::Isometry3d> robots;  // C_world_new_old of each robot's other poses
  std::map<Key, Eigen::Isometry3d> pinned;       // C_world_new_old of each pinned pose (gauge: identity)

  // The correction of pose `key` (identity for what the step did not reach).
  Eigen::Isometry3d of(Key key) const;
};

class DistributedRobot {
 public:
  // Takes robot's poses (current values of graph.poses, used as the starting point of its own
  // chordal initialisation) and the factors touching them. `gauge`: a key held at its current
  // pose when it is this robot's (none when priors fix the gauge).
  DistributedRobot(const PoseGraph& graph, uint32_t robot, std::optional<Key> gauge);

  uint32_t robot() const noexcept { return robot_; }
  // Own separator keys, each with the robots that need it (its inter-robot factors' other ends).
  const std::map<Key, std::set<uint32_t>>& audience() const noexcept { return audience_; }
  // The neighbours' keys this robot needs.
  const std::set<Key>& needed() const noexcept { return needed_; }

  // Stage 1. One round of the rotation relaxation with the received separator rotations; the own
  // values move `omega` of the way to the block solution (1: Gauss-Seidel). Returns the largest
  // change of an own M (Frobenius norm); infinity when nothing places the robot yet (no neighbour
  // value received, no gauge, no prior: the round leaves it as it is). The same holds for the
  // other stages' rounds.
  double rotation_round(const SeparatorRotations& received, double omega);
  SeparatorRotations rotation_separators() const;
  // Ends stage 1: projects the own relaxed rotations and the neighbours' last ones onto SO(3).
  void end_rotations(const SeparatorRotations& received);

  // Stage 2. One round of the translation problem; returns the largest position change [m].
  double translation_round(const SeparatorTranslations& received, double omega);
  SeparatorTranslations translation_separators() const;

  // Stage 3. One round of the nonlinear block solve with the received separator poses; each own
  // pose moves `gamma` of the way to the block solution. Returns the largest change [m, rad].
  double pose_round(const SeparatorPoses& received, const SolverOptions& options, double gamma);
  SeparatorPoses pose_separators() const;
  // What the coarse step needs from this robot: the separator poses, and the pinned poses (the
  // gauge, the poses with a prior) with the own poses they share a factor with.
  SeparatorPoses coarse_separators() const;
  // Applies the robot's share of the coarse step to every own pose a factor names: T <- C * T.
  // Returns the largest change [m, rad].
  double move(const CoarseCorrections& corrections);

  // The own poses T_world_key (after stage 2: rotations and translations of stages 1-2).
  const std::map<Key, Eigen::Isometry3d>& poses() const noexcept { return poses_; }

 private:
  uint32_t robot_;
  std::optional<Key> gauge_;  // own key held fixed, if any
  int dimension_ = 3;
  std::vector<Factor> factors_;  // every factor touching an own pose
  std::vector<detail::LinearTerm> rotation_terms_;
  std::vector<detail::LinearTerm> translation_terms_;  // built when stage 1 ends
  std::map<Key, Eigen::Isometry3d> poses_;
  std::set<Key> linked_;                    // own keys some factor names (the unknowns of the linear stages)
  std::set<Key> pinned_;                    // own gauge and own poses with a prior
  std::map<Key, Eigen::Matrix3d> relaxed_;  // stage 1 unknowns M
  std::map<Key, Eigen::Matrix3d> neighbour_rotations_;  // projected, after stage 1
  std::map<Key, std::set<uint32_t>> audience_;
  std::set<Key> needed_;
};

// The robot-level (coarse) problem of stage 3: every robot's poses move rigidly, T <- C_r T,
// except the pinned poses (the gauge, which stays put, and each pose with a prior, which moves on
// its own). Solves for the corrections that minimise `factors` (the inter-robot factors, the priors
// and the factors at pinned poses; the others do not change under such moves) from `poses`, the
// current estimates of the poses they name. Block solves leave the errors that span several robots
// (a bend or turn of the whole map made of nearly rigid moves of each robot, or of the map about a
// pinned pose) to shrink slowly; this step removes them in one solve of 6 unknowns per robot and
// pinned pose. Every robot can solve it from the same data and get the same corrections.
CoarseCorrections coarse_corrections(const std::vector<Factor>& factors, const SeparatorPoses& poses,
                                     std::optional<Key> gauge, const SolverOptions& options, int dimension);

}  // namespace cdc::graph
