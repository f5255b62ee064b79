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

// Graduated non-convexity (Yang, Antonante, Tzoumas and Carlone, RA-L 2020) with the truncated
// least-squares surrogate, on the factors marked robust (loop closures, intra- and inter-robot);
// odometry and priors stay quadratic. A weight w_i in [0, 1] scales each robust factor's squared
// residual s_i = r_i^T Omega_i r_i (with the solve's objective). From the initial values (or the
// least-squares solution), mu starts at c^2 / (2 max s_i - c^2) and grows by mu_step per round; each
// round sets
//   w_i = 1                                   for s_i <= mu / (mu + 1) c^2
//   w_i = c sqrt(mu (mu + 1) / s_i) - mu      between
//   w_i = 0                                   for s_i >= (mu + 1) / mu c^2
// and re-solves the weighted problem from the previous solution. As mu grows the surrogate tends to
// the truncated cost min(s_i, c^2), and the weights to 0 (outlier) or 1 (inlier). Off by default: a
// service switches it on for the solves that need it (each round is a full solve).
struct GncOptions {
  bool enabled = false;
  // c^2: a loop whose squared weighted residual exceeds it at the solution is an outlier
  // (the chi-square quantile of 6 DoF at 99 %).
  double inlier_threshold = 16.81;
  double mu_step = 1.4;
  int max_rounds = 200;
  // Rounds stop once every weight is within this of 0 or 1 and mu has reached 1.
  double weight_tolerance = 1e-4;
  // Where the rounds start: the least-squares solution (every weight 1), or the initial values as
  // given (from odometry alone, the wrong loops stand out; at a least-squares solution they have
  // pulled the poses towards themselves).
  bool least_squares_start = false;
  // With least_squares_start: no rounds when the least-squares solve stops short of convergence (a
  // bounded incremental pass), since residuals away from the solution single out no outlier; the
  // result is that solve's, every weight 1 and gnc_converged false.
  bool require_converged_start = false;
  // Relative cost change at which a round whose weights are not yet settled stops (the final
  // round uses SolverOptions::function_tolerance).
  double round_function_tolerance = 1e-6;
  // The threshold assumes information that matches the measurements' noise. Where the information
  // is far more pessimistic (loops that fit 100 times better than it says), a wrong loop that a
  // long, flexible trajectory can bend to costs less than c^2 and is accepted. With
  // calibrate_threshold, once the rounds settle, c^2 becomes median_ratio times the accepted loops'
  // median s (a residual 10 times the median one, for the default), and GNC runs again from the
  // same start, when that is below half of the last threshold (never above inlier_threshold), at
  // most max_calibrations times.
  bool calibrate_threshold = false;
  double median_ratio = 100.0;
  int max_calibrations = 4;
};

struct SolverOptions {
  SparseBackend sparse_backend = SparseBackend::kSuiteSparse;
  Objective objective = Objective::kFullInformation;
  int max_iterations = 100;
  double max_time_s = 1e6;
  double function_tolerance = 1e-12;
  double gradient_tolerance = 1e-12;
  double parameter_tolerance = 1e-12;
  double robust_loss_scale = 0.0;  // > 0: Cauchy loss with this scale on factors marked robust
  GncOptions gnc;                  // enabled: GNC weights on factors marked robust instead of Cauchy
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
  bool converged = false;  // Ceres converged (with GNC: in its last round)
  bool failed = false;     // Ceres gave up (a linear solver failure, a cost that is not finite): no solution
  int iterations = 0;      // Ceres iterations, summed over GNC's rounds
  double time_s = 0;
  double initial_cost = 0;  // objective before, without the 1/2 factor, every factor at full weight
  double final_cost = 0;    // objective after, without the 1/2 factor, every factor at full weight
  std::string message;      // Ceres' termination message
  std::string report;       // Ceres' full report when requested
  // Per iteration (0 = start): solver time since the start [s] and Ceres' cost (with its 1/2);
  // with GNC, every round's iterations in turn, each round's cost with its weights.
  std::vector<std::pair<double, double>> trace;
  // GNC only (empty and 0 otherwise): the final weight of every factor of the graph, in its order
  // (1 for factors not marked robust), and the number of rounds after the least-squares solve.
  std::vector<double> weights;
  int gnc_rounds = 0;          // over both passes with calibrate_threshold
  double gnc_threshold = 0;    // the threshold c^2 of the last pass
  bool gnc_converged = false;  // every weight ended within weight_tolerance of 0 or 1
};

// Weights above this count as accepted loops.
inline constexpr double kGncAcceptedWeight = 0.5;

// Optimises graph.poses in place. Keys in `fixed` stay constant; when the graph has no prior and
// nothing is fixed, the first pose is held fixed (gauge).
SolveResult solve(PoseGraph& graph, const SolverOptions& options, const std::set<Key>& fixed = {});

}  // namespace cdc::graph
