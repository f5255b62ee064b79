#include "cdc/graph/solver.hpp"

#include "cdc/graph/objective.hpp"
#include "residuals.hpp"

#include <Eigen/Cholesky>

#include <cmath>
#include <memory>
#include <unordered_map>
#include <utility>

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

// One residual per factor, in the order of the graph's factors; robust factors share `robust`
// (null: none). Returns whether some factor is a prior.
bool add_factors(const PoseGraph& graph, Objective objective, ceres::LossFunction* robust, PoseBlocks& blocks,
                 ceres::Problem& problem) {
  bool has_prior = false;
  for (const Factor& f : graph.factors) {
    PoseBlock& a = blocks.at(f.a);
    if (f.kind == FactorKind::kPrior) {
      problem.AddResidualBlock(detail::PriorResidual::create(f.measurement, sqrt_information(f.information)), nullptr,
                               a.t, a.q);
      has_prior = true;
      continue;
    }
    PoseBlock& b = blocks.at(f.b);
    ceres::LossFunction* loss = f.robust ? robust : nullptr;
    problem.AddResidualBlock(
        detail::BetweenResidual::create(f.measurement, between_sqrt_information(f, objective, graph.dimension)), loss,
        a.t, a.q, b.t, b.q);
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

void record_summary(const ceres::Solver::Summary& summary, bool full_report, SolveResult& result) {
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  // A cost that overflowed "converges" (its relative change is NaN): no solution either.
  result.failed =
      summary.termination_type == ceres::FAILURE || !summary.IsSolutionUsable() || !std::isfinite(summary.final_cost);
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.time_s = summary.total_time_in_seconds;
  result.message = summary.message;
  for (const auto& it : summary.iterations) {
    result.trace.emplace_back(it.cumulative_time_in_seconds, it.cost);
  }
  if (full_report) {
    result.report = summary.FullReport();
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
  // One robust loss shared by every robust factor, owned here (outlives the problem).
  std::unique_ptr<ceres::LossFunction> robust;
  if (options.robust_loss_scale > 0.0) {
    robust = std::make_unique<ceres::CauchyLoss>(options.robust_loss_scale);
  }
  PoseManifolds manifolds;
  ceres::Problem problem(popts);
  const bool has_prior = add_factors(graph, options.objective, robust.get(), blocks, problem);
  manifolds.apply(blocks, graph.dimension == 2, problem);
  hold_fixed(graph, fixed, has_prior, blocks, problem);

  ceres::Solver::Summary summary;
  ceres::Solver::Options sopts = ceres_options(options);
  IterationHook hook(options.on_iteration);
  if (options.on_iteration) sopts.callbacks.push_back(&hook);
  ceres::Solve(sopts, &problem, &summary);
  from_blocks(blocks, graph);
  record_summary(summary, options.full_report, result);
  result.final_cost = objective(graph, options.objective);
  return result;
}

}  // namespace cdc::graph
