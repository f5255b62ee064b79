// Distributed pose-graph optimisation over robots, simulated: the exchange between robots is a
// function call, the bytes are counted. Two algorithms:
//  - solve_distributed_two_stage (distributed_robot.hpp): rotations, then translations, then poses
//    with a coarse step; converges to the centralized estimate in shape, not only in cost;
//  - solve_distributed: block Gauss-Seidel over robots on the poses (in the spirit of DGS) from a
//    rigid placement of the robots (initialise_distributed); robots exchange only separator poses.
//    It reaches the centralized cost quickly but leaves a slow bend of the whole map.
#pragma once

#include "cdc/graph/distributed_robot.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/graph/solver.hpp"

#include <cstdint>
#include <map>
#include <vector>

namespace cdc::graph {

// The two-stage solve (solve_distributed_two_stage, see distributed_robot.hpp).
struct TwoStageOptions {
  // Stages 1 and 2 give stage 3 a start whose rotations agree between robots; stage 3 with the
  // coarse step removes what they leave, so they end early: when no robot changed an own value by
  // more than the tolerance in a round (Frobenius norm of a relaxed rotation; [m]), or after their
  // round limit.
  int max_rotation_rounds = 3;
  double rotation_tolerance = 1e-2;
  int max_translation_rounds = 3;
  double translation_tolerance = 1e-2;
  // Block successive over-relaxation factor of the linear stages from their second round on
  // (1: Gauss-Seidel; 1 < w < 2 converges for these symmetric positive definite problems).
  double linear_over_relaxation = 1.5;
  // Over-relaxation of the block solves of stage 3.
  double pose_over_relaxation = 1.3;
  // The coarse step after every round of stage 3 (coarse_corrections). It needs every robot's
  // separator poses, so each robot sends its separators to all robots instead of its neighbours.
  bool coarse = true;
  // All robots update at once from the estimates sent in the previous round (block Jacobi, what
  // robots do when nobody waits for anybody) instead of one after the other in the order of their
  // ids (block Gauss-Seidel). Parallel updates take no over-relaxation (factors above 1 are used
  // as 1): block Jacobi over-relaxed diverges on strongly coupled robots.
  bool parallel = false;
};

struct DistributedOptions {
  int max_rounds = 30;
  // Stop when no robot moved a pose by more than this in a round [m, rad] (1 mm, 1 mrad).
  double pose_change_tolerance = 1e-3;
  // Successive over-relaxation: each pose moves gamma times its local update (translation
  // linearly, rotation along the geodesic). 1 is plain Gauss-Seidel; 1 < gamma < 2 speeds up the
  // slow, smooth error modes that Gauss-Seidel leaves behind.
  double over_relaxation = 1.7;
  SolverOptions local;  // the per-robot solve
  TwoStageOptions two_stage;
};

struct DistributedResult {
  int rounds = 0;
  bool converged = false;
  std::vector<double> objective_per_round;  // after initialisation (index 0) and each round
  std::map<uint32_t, uint64_t> bytes_sent;  // separator poses sent, per robot [bytes]
  std::map<uint32_t, uint64_t> poses_sent;  // separator estimates sent, per robot (every stage)
  // objective_per_round[i] is the objective after round objective_first_round + i (two-stage: no
  // objective exists before stage 2 ends).
  int objective_first_round = 0;
  std::vector<uint64_t> bytes_per_round;  // all robots together
  int rotation_rounds = 0;                // two-stage: rounds of stage 1
  int translation_rounds = 0;             // two-stage: rounds of stage 2
  std::map<uint32_t, double> compute_s;   // two-stage: time each robot spent on its own solves [s]
};

// Bytes of one separator pose on the wire (cdc_msg_KeyframePoseF): keyframe id + position and quaternion in 7 floats.
inline constexpr uint64_t kSeparatorPoseBytes = 4 + 7 * 4;

// Each robot initialises its own subgraph (chordal), then is placed in the world by a rigid fit
// to all its inter-robot factors with already placed robots (robot of the smallest key anchors).
// Returns false when some robot cannot be reached through inter-robot factors.
bool initialise_distributed(PoseGraph& graph, DistributedResult* accounting = nullptr);

// Optimises graph.poses in place by rounds of block Gauss-Seidel over robots. The robot of the
// smallest key holds its first pose fixed (gauge). Objective values use options.local.objective.
DistributedResult solve_distributed(PoseGraph& graph, const DistributedOptions& options);

// The two-stage solve (distributed_robot.hpp) from each robot's own chordal initialisation, in
// rounds of block Gauss-Seidel: robots update in the order of their ids, each with the latest
// separator estimates of its neighbours. max_rounds bounds the rounds of all three stages; a
// separator estimate is counted once per robot that needs it. The gauge is the smallest key's
// current pose unless the graph has priors. Writes the estimate into graph.poses; `converged` says
// that stage 3 met pose_change_tolerance within the rounds.
DistributedResult solve_distributed_two_stage(PoseGraph& graph, const DistributedOptions& options);

}  // namespace cdc::graph
