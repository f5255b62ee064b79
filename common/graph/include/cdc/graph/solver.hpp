// Non-linear least-squares solve of a pose graph with Ceres (LM, sparse normal Cholesky through
// SuiteSparse, quaternion manifold).
#pragma once

#include "cdc/graph/pose_graph.hpp"

#include <functional>
#include <set>
#include <string>
#include <vector>

namespace cdc::graph {

enum class Objective {
  kFullInformation,  // r = sqrt(Omega) (t_err, 2 vec(q_err)), as in Ceres' pose_graph_3d
  kSeSync            // SE-Sync's isotropic chordal objective (see objective.hpp)
};

// Sparse Cholesky library behind Ceres' SPARSE_NORMAL_CHOLESKY.
enum class SparseBackend { kSuiteSparse, kEigen, kCxSparse };

struct SolverOptions {
  SparseBackend sparse_backend = SparseBackend::kSuiteSparse;
  Objective objective = Objective::kFullInformation;
  int max_iterations = 100;
  double max_time_s = 1e6;
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-12;
  double robust_loss_scale = 0.0;  // > 0: Cauchy loss with this scale on factors marked robust
  int threads = 1;
  // Levenberg-Marquardt's initial trust-region radius (1 / initial damping). Ceres' default is
  // 1e4; from a good initial estimate (chordal) nearly Gauss-Newton steps converge in a few
  // iterations (parking-garage: 2 instead of 18), and LM still shrinks the region after a
  // rejected step.
  double initial_trust_region_radius = 1e12;
  bool full_report = false;  // fill SolveResult::report with Ceres' full report
  // Called after every iteration, on the solving thread: a service asserts its liveliness from it
  // while a large graph is solved.
  std::function<void()> on_iteration;
};

struct SolveResult {
  bool converged = false;
  bool failed = false;  // Ceres gave up (a linear solver failure, a cost that is not finite): no solution
  int iterations = 0;
  double time_s = 0;
  double initial_cost = 0;  // objective before, without the 1/2 factor
  double final_cost = 0;    // objective after, without the 1/2 factor
  std::string message;      // Ceres' termination message
  std::string report;       // Ceres' full report when requested
  // Per iteration (0 = start): solver time since the start [s] and Ceres' cost (with its 1/2).
  std::vector<std::pair<double, double>> trace;
};

// Optimises graph.poses in place. Keys in `fixed` stay constant; when the graph has no prior and
// nothing is fixed, the first pose is held fixed (gauge).
SolveResult solve(PoseGraph& graph, const SolverOptions& options, const std::set<Key>& fixed = {});

}  // namespace cdc::graph
