#include "cdc/graph/solver.hpp"

#include "cdc/graph/objective.hpp"
#include "residuals.hpp"

#include <Eigen/Cholesky>

#include <memory>
#include <unordered_map>

namespace cdc::graph {
namespace {

struct PoseBlock {
  double t[3];
  double q[4];  // x, y, z, w
};

Matrix6d sqrt_information(const Matrix6d& info) {
  // Upper-triangular L^T with info = L L^T, so r^T info r = |L^T r|^2.
  return info.llt().matrixL().transpose();
}

double objective(const PoseGraph& g, Objective o) {
  return o == Objective::kSeSync ? sesync_objective(g) : full_information_cost(g);
}

}  // namespace

SolveResult solve(PoseGraph& graph, const SolverOptions& options, const std::set<Key>& fixed) {
  SolveResult result;
  result.initial_cost = objective(graph, options.objective);

  std::unordered_map<Key, PoseBlock> blocks;
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

  ceres::Problem::Options popts;
  popts.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  popts.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  // One robust loss shared by every robust factor, owned here (outlives the problem).
  std::unique_ptr<ceres::LossFunction> robust;
  if (options.robust_loss_scale > 0.0) {
    robust = std::make_unique<ceres::CauchyLoss>(options.robust_loss_scale);
  }
  ceres::Problem problem(popts);
  ceres::EigenQuaternionManifold quaternion_manifold;
  // Planar graphs stay planar: z held, rotation about z only.
  ceres::SubsetManifold planar_translation(3, {2});
  ceres::AutoDiffManifold<detail::YawOnlyQuaternion, 4, 1> yaw_only;
  const bool planar = graph.dimension == 2;

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
    ceres::LossFunction* loss = f.robust ? robust.get() : nullptr;
    // SE-Sync's objective is the same residual with isotropic information diag(tau I, 2 kappa I):
    // ||R_j - R_i R_ij||_F^2 = 8 sin^2(theta/2) = 2 * |2 vec(q_err)|^2, and the translation term is
    // rotation invariant. This form is far closer to linear in the tangent space than the
    // residual vec(R_j - R_i R_ij): on sphere2500 LM needs 10 iterations instead of 58.
    Matrix6d sqrt_info;
    if (options.objective == Objective::kSeSync) {
      const IsotropicWeights w = isotropic_weights(f, graph.dimension);
      sqrt_info.setZero();
      sqrt_info.diagonal() << std::sqrt(w.tau), std::sqrt(w.tau), std::sqrt(w.tau), std::sqrt(2.0 * w.kappa),
          std::sqrt(2.0 * w.kappa), std::sqrt(2.0 * w.kappa);
    } else {
      sqrt_info = sqrt_information(f.information);
    }
    problem.AddResidualBlock(detail::BetweenResidual::create(f.measurement, sqrt_info), loss, a.t, a.q, b.t, b.q);
  }
  for (auto& [k, b] : blocks) {
    if (problem.HasParameterBlock(b.q)) {
      problem.SetManifold(b.q, planar ? static_cast<ceres::Manifold*>(&yaw_only) : &quaternion_manifold);
      if (planar) {
        problem.SetManifold(b.t, &planar_translation);
      }
    }
  }
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

  ceres::Solver::Options sopts;
  sopts.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  switch (options.sparse_backend) {
    case SparseBackend::kSuiteSparse: sopts.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE; break;
    case SparseBackend::kEigen: sopts.sparse_linear_algebra_library_type = ceres::EIGEN_SPARSE; break;
    case SparseBackend::kCxSparse: sopts.sparse_linear_algebra_library_type = ceres::CX_SPARSE; break;
  }
  sopts.max_num_iterations = options.max_iterations;
  sopts.max_solver_time_in_seconds = options.max_time_s;
  sopts.function_tolerance = options.function_tolerance;
  sopts.gradient_tolerance = options.gradient_tolerance;
  sopts.parameter_tolerance = options.parameter_tolerance;
  sopts.num_threads = options.threads;
  sopts.initial_trust_region_radius = options.initial_trust_region_radius;
  sopts.logging_type = options.full_report ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(sopts, &problem, &summary);

  for (auto& [k, T] : graph.poses) {
    const PoseBlock& b = blocks.at(k);
    T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Quaterniond(b.q[3], b.q[0], b.q[1], b.q[2]).normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(b.t[0], b.t[1], b.t[2]);
  }
  result.converged = summary.termination_type == ceres::CONVERGENCE;
  result.iterations = static_cast<int>(summary.iterations.size()) - 1;
  result.time_s = summary.total_time_in_seconds;
  result.final_cost = objective(graph, options.objective);
  result.message = summary.message;
  for (const auto& it : summary.iterations) {
    result.trace.emplace_back(it.cumulative_time_in_seconds, it.cost);
  }
  if (options.full_report) {
    result.report = summary.FullReport();
  }
  return result;
}

}  // namespace cdc::graph
