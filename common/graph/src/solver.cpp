#include "cdc/graph/solver.hpp"

#include "cdc/graph/objective.hpp"
#include "residuals.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <cmath>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

namespace cdc::graph {
namespace {

struct PoseBlock {
  double t[3];
  double q[4];  // x, y, z, w
};

using PoseBlocks = std::unordered_map<Key, PoseBlock>;

PoseBlocks to_blocks(const PoseGraph& graph) {
  PoseBlocks blocks;
  blocks.reserve(graph.poses.size());
  for (const auto& [k, T] : graph.poses) {
    PoseBlock b{};
    const Eigen::Vector3d t = T.translation();
    const Eigen::Quaterniond q(T.rotation());
    b.t[0] = t.x();
    b.t[1] = t.y();
    b.t[2] = t.z();
    b.q[0] = q.x();
    b.q[1] = q.y();
    b.q[2] = q.z();
    b.q[3] = q.w();
    blocks.emplace(k, b);
  }
  return blocks;
}

void from_blocks(const PoseBlocks& blocks, PoseGraph& graph) {
  for (auto& [k, T] : graph.poses) {
    const PoseBlock& b = blocks.at(k);
    T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(b.q[3], b.q[0], b.q[1], b.q[2]).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(b.t[0], b.t[1], b.t[2]);
  }
}

Matrix6d sqrt_information(const Matrix6d& info) {
  // Upper-triangular L^T with info = L L^T, so r^T info r = |L^T r|^2.
  return info.llt().matrixL().transpose();
}

// The square-root weight of a between factor under the objective. SE-Sync's objective is the same
// residual with isotropic information diag(tau I, 2 kappa I): ||R_j - R_i R_ij||_F^2 = 8 sin^2(theta/2)
// = 2 * |2 vec(q_err)|^2, and the translation term is rotation invariant. This form is far closer to
// linear in the tangent space than the residual vec(R_j - R_i R_ij): on sphere2500 LM needs 10
// iterations instead of 58.
Matrix6d between_sqrt_information(const Factor& f, Objective objective, int dimension) {
  if (objective != Objective::kSeSync) {
    return sqrt_information(f.information);
  }
  const IsotropicWeights w = isotropic_weights(f, dimension);
  Matrix6d sqrt_info = Matrix6d::Zero();
  sqrt_info.diagonal() << std::sqrt(w.tau), std::sqrt(w.tau), std::sqrt(w.tau), std::sqrt(2.0 * w.kappa),
      std::sqrt(2.0 * w.kappa), std::sqrt(2.0 * w.kappa);
  return sqrt_info;
}

// A robust factor's GNC weight w as a loss: rho(s) = w s. The weight lives outside (GNC sets it
// between solves of one problem).
class WeightLoss : public ceres::LossFunction {
 public:
  explicit WeightLoss(const double* weight) : w_(weight) {}
  void Evaluate(double s, double rho[3]) const override {
    rho[0] = *w_ * s;
    rho[1] = *w_;
    rho[2] = 0.0;
  }

 private:
  const double* w_;
};

// The loss of each factor: none for factors not marked robust; for robust ones the shared Cauchy
// loss (null: none) or, with GNC, a weight per factor.
struct Losses {
  ceres::LossFunction* cauchy = nullptr;
  std::vector<double> weights;                     // GNC: one per factor of the graph
  std::vector<std::unique_ptr<WeightLoss>> owned;  // GNC: one per robust factor

  ceres::LossFunction* of(const Factor& f, size_t i) {
    if (!f.robust) return nullptr;
    if (weights.empty()) return cauchy;
    owned.push_back(std::make_unique<WeightLoss>(&weights[i]));
    return owned.back().get();
  }
};

// One residual per factor, in the order of the graph's factors (their ids in `ids`). Returns
// whether some factor is a prior.
bool add_factors(const PoseGraph& graph, Objective objective, Losses& losses, PoseBlocks& blocks,
                 ceres::Problem& problem, std::vector<ceres::ResidualBlockId>& ids) {
  bool has_prior = false;
  for (size_t i = 0; i < graph.factors.size(); ++i) {
    const Factor& f = graph.factors[i];
    PoseBlock& a = blocks.at(f.a);
    if (f.kind == FactorKind::kPrior) {
      ids.push_back(problem.AddResidualBlock(
          detail::PriorResidual::create(f.measurement, sqrt_information(f.information)), nullptr, a.t, a.q));
      has_prior = true;
      continue;
    }
    PoseBlock& b = blocks.at(f.b);
    ids.push_back(problem.AddResidualBlock(
        detail::BetweenResidual::create(f.measurement, between_sqrt_information(f, objective, graph.dimension)),
        losses.of(f, i), a.t, a.q, b.t, b.q));
  }
  return has_prior;
}

// The manifolds of the pose blocks, owned here (they outlive the problem that borrows them).
// Planar graphs stay planar: z held, rotation about z only.
struct PoseManifolds {
  ceres::EigenQuaternionManifold quaternion;
  ceres::SubsetManifold planar_translation{3, {2}};
  ceres::AutoDiffManifold<detail::YawOnlyQuaternion, 4, 1> yaw_only;

  void apply(PoseBlocks& blocks, bool planar, ceres::Problem& problem) {
    for (auto& [k, b] : blocks) {
      if (problem.HasParameterBlock(b.q)) {
        problem.SetManifold(b.q, planar ? static_cast<ceres::Manifold*>(&yaw_only) : &quaternion);
        if (planar) {
          problem.SetManifold(b.t, &planar_translation);
        }
      }
    }
  }
};

// Holds the poses in `fixed` constant; with neither a prior nor a fixed pose, the first pose (gauge).
void hold_fixed(const PoseGraph& graph, const std::set<Key>& fixed, bool has_prior, PoseBlocks& blocks,
                ceres::Problem& problem) {
  auto hold = [&](Key k) {
    PoseBlock& b = blocks.at(k);
    if (problem.HasParameterBlock(b.t)) {
      problem.SetParameterBlockConstant(b.t);
      problem.SetParameterBlockConstant(b.q);
    }
  };
  for (Key k : fixed) {
    if (blocks.count(k) != 0) {
      hold(k);
    }
  }
  if (!has_prior && fixed.empty() && !graph.poses.empty()) {
    hold(graph.poses.begin()->first);  // gauge freedom
  }
}

// Hands each finished iteration to SolverOptions::on_iteration; never stops the solve.
class IterationHook : public ceres::IterationCallback {
 public:
  explicit IterationHook(std::function<void()> f) : f_(std::move(f)) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    f_();
    return ceres::SOLVER_CONTINUE;
  }

 private:
  std::function<void()> f_;
};

ceres::Solver::Options ceres_options(const SolverOptions& options) {
  ceres::Solver::Options sopts;
  sopts.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  switch (options.sparse_backend) {
    case SparseBackend::kSuiteSparse:
      sopts.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
      break;
    case SparseBackend::kEigen:
      sopts.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE;
      break;
    case SparseBackend::kCxSparse:
      sopts.sparse_linear_algebra_library_type = ceres::CX_SPARSE;
      break;
  }
  sopts.max_num_iterations = options.max_iterations;
  sopts.max_solver_time_in_seconds = options.max_time_s;
  sopts.function_tolerance = options.function_tolerance;
  sopts.gradient_tolerance = options.gradient_tolerance;
  sopts.parameter_tolerance = options.parameter_tolerance;
  sopts.num_threads = options.threads;
  sopts.initial_trust_region_radius = options.initial_trust_region_radius;
  sopts.logging_type = options.full_report ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
  return sopts;
}

// Solves the problem from its current values and adds the run to the result (iterations, time and
// trace accumulate over GNC's rounds).
void run_solve(const ceres::Solver::Options& sopts, bool full_report, ceres::Problem& problem, SolveResult& result) {
  ceres::Solver::Summary summary;
  ceres::Solve(sopts, &problem, &summary);
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  // A cost that overflowed "converges" (its relative change is NaN): no solution either.
  result.failed =
      summary.termination_type == ceres::FAILURE || !summary.IsSolutionUsable() || !std::isfinite(summary.final_cost);
  const double t0 = result.time_s;
  result.iterations += static_cast<int>(summary.iterations.size()) - 1;
  result.time_s += summary.total_time_in_seconds;
  result.message = summary.message;
  for (const auto& it : summary.iterations) {
    result.trace.emplace_back(t0 + it.cumulative_time_in_seconds, it.cost);
  }
  if (full_report) {
    result.report += summary.FullReport();
  }
}

// s_i = r_i^T Omega_i r_i of every robust factor at the problem's current values (0 for the others).
std::vector<double> squared_residuals(const PoseGraph& graph, ceres::Problem& problem,
                                      const std::vector<ceres::ResidualBlockId>& ids) {
  std::vector<double> s(ids.size(), 0.0);
  for (size_t i = 0; i < ids.size(); ++i) {
    if (graph.factors[i].robust) {
      double half_s = 0.0;
      problem.EvaluateResidualBlock(ids[i], /*apply_loss_function=*/false, &half_s, nullptr, nullptr);
      s[i] = 2.0 * half_s;
    }
  }
  return s;
}

// The weight minimising the truncated-least-squares surrogate at mu for a squared residual s.
double tls_weight(double s, double c2, double mu) {
  if (s <= mu / (mu + 1.0) * c2) return 1.0;
  if (s >= (mu + 1.0) / mu * c2) return 0.0;
  return std::sqrt(c2 * mu * (mu + 1.0) / s) - mu;
}

// GNC's rounds from the problem's current values (see GncOptions); leaves the weights in w.
void run_gnc(const PoseGraph& graph, const GncOptions& o, const ceres::Solver::Options& sopts, bool full_report,
             ceres::Problem& problem, const std::vector<ceres::ResidualBlockId>& ids, std::vector<double>& w,
             SolveResult& result) {
  const double c2 = o.inlier_threshold;
  std::vector<double> s = squared_residuals(graph, problem, ids);
  const double s_max = s.empty() ? 0.0 : *std::max_element(s.begin(), s.end());
  if (s_max <= c2) {
    // Every loop within the threshold: the least-squares solution is the truncated optimum.
    if (!o.least_squares_start) run_solve(sopts, full_report, problem, result);
    result.gnc_converged = !result.failed;
    return;
  }
  double mu = c2 / (2.0 * s_max - c2);
  // Rounds whose weights are still moving need no tight convergence; the last one gets it.
  ceres::Solver::Options round = sopts;
  round.function_tolerance = std::max(sopts.function_tolerance, o.round_function_tolerance);
  while (result.gnc_rounds < o.max_rounds) {
    // Settled: every weight 0 or 1 with mu past 1. At a small mu every weight may be near 0
    // (all residuals far above c^2 at the start) without any decision taken.
    bool settled = mu >= 1.0;
    for (size_t i = 0; i < w.size(); ++i) {
      if (graph.factors[i].robust) {
        w[i] = tls_weight(s[i], c2, mu);
        settled = settled && std::min(w[i], 1.0 - w[i]) <= o.weight_tolerance;
      }
    }
    run_solve(settled ? sopts : round, full_report, problem, result);
    ++result.gnc_rounds;
    if (result.failed) return;
    if (settled) {
      result.gnc_converged = true;
      return;
    }
    s = squared_residuals(graph, problem, ids);
    mu *= o.mu_step;
  }
}

// The median squared residual s of the loops of weight above kGncAcceptedWeight (1 if none).
double accepted_median(const PoseGraph& graph, ceres::Problem& problem, const std::vector<ceres::ResidualBlockId>& ids,
                       const std::vector<double>& w) {
  const std::vector<double> s = squared_residuals(graph, problem, ids);
  std::vector<double> accepted;
  for (size_t i = 0; i < s.size(); ++i) {
    if (graph.factors[i].robust && w[i] > kGncAcceptedWeight) accepted.push_back(s[i]);
  }
  if (accepted.empty()) return 1.0;
  const auto mid = accepted.begin() + static_cast<std::ptrdiff_t>(accepted.size() / 2);
  std::nth_element(accepted.begin(), mid, accepted.end());
  return *mid;
}

// GNC from the poses in `blocks`; with calibrate_threshold, another pass from the same start while
// the accepted loops' median residual puts the threshold below half of the last pass's (wrong loops
// accepted in a pass bend the poses and inflate that median, so one pass may not be enough).
void solve_gnc(const PoseGraph& graph, const GncOptions& gnc, const ceres::Solver::Options& sopts, bool full_report,
               ceres::Problem& problem, const std::vector<ceres::ResidualBlockId>& ids, PoseBlocks& blocks,
               std::vector<double>& w, SolveResult& result) {
  const PoseBlocks start = blocks;
  GncOptions pass = gnc;
  for (int attempt = 0; attempt <= gnc.max_calibrations; ++attempt) {
    if (attempt > 0) {
      for (auto& [k, b] : blocks) b = start.at(k);  // the problem keeps the blocks' addresses
      std::fill(w.begin(), w.end(), 1.0);
      result.gnc_converged = false;
    }
    if (pass.least_squares_start) {
      run_solve(sopts, full_report, problem, result);
      if (pass.require_converged_start && !result.converged) return;
    }
    if (!result.failed) run_gnc(graph, pass, sopts, full_report, problem, ids, w, result);
    result.gnc_threshold = pass.inlier_threshold;
    if (result.failed || !gnc.calibrate_threshold) return;
    const double calibrated = gnc.median_ratio * accepted_median(graph, problem, ids, w);
    if (calibrated >= 0.5 * pass.inlier_threshold) return;
    pass.inlier_threshold = calibrated;
  }
}

double objective(const PoseGraph& g, Objective o) {
  return o == Objective::kSeSync ? sesync_objective(g) : full_information_cost(g);
}

}  // namespace

SolveResult solve(PoseGraph& graph, const SolverOptions& options, const std::set<Key>& fixed) {
  SolveResult result;
  result.initial_cost = objective(graph, options.objective);
  PoseBlocks blocks = to_blocks(graph);

  ceres::Problem::Options popts;
  popts.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  popts.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  // The losses and manifolds are owned here and outlive the problem that borrows them.
  std::unique_ptr<ceres::LossFunction> cauchy;
  Losses losses;
  if (options.gnc.enabled) {
    losses.weights.assign(graph.factors.size(), 1.0);
  } else if (options.robust_loss_scale > 0.0) {
    cauchy = std::make_unique<ceres::CauchyLoss>(options.robust_loss_scale);
    losses.cauchy = cauchy.get();
  }
  PoseManifolds manifolds;
  ceres::Problem problem(popts);
  std::vector<ceres::ResidualBlockId> ids;
  const bool has_prior = add_factors(graph, options.objective, losses, blocks, problem, ids);
  manifolds.apply(blocks, graph.dimension == 2, problem);
  hold_fixed(graph, fixed, has_prior, blocks, problem);

  ceres::Solver::Options sopts = ceres_options(options);
  IterationHook hook(options.on_iteration);
  if (options.on_iteration) sopts.callbacks.push_back(&hook);
  if (options.gnc.enabled) {
    solve_gnc(graph, options.gnc, sopts, options.full_report, problem, ids, blocks, losses.weights, result);
    result.weights = losses.weights;
  } else {
    run_solve(sopts, options.full_report, problem, result);
  }
  from_blocks(blocks, graph);
  result.final_cost = objective(graph, options.objective);
  return result;
}

}  // namespace cdc::graph
