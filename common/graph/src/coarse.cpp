// The robot-level (coarse) problem of the two-stage solve's stage 3.
#include "cdc/graph/distributed_robot.hpp"
#include "cdc/graph/objective.hpp"
#include "residuals.hpp"

#include <cmath>
#include <memory>

namespace cdc::graph {
namespace {

// A pose moved rigidly with its robot: C * T with C = (ct, cq), as (t, q).
template <typename T>
void moved(const T* ct, const T* cq, const Eigen::Isometry3d& pose, Eigen::Matrix<T, 3, 1>& t,
           Eigen::Quaternion<T>& q) {
  Eigen::Map<const Eigen::Matrix<T, 3, 1>> c_t(ct);
  Eigen::Map<const Eigen::Quaternion<T>> c_q(cq);
  q = c_q * Eigen::Quaterniond(pose.rotation()).template cast<T>();
  t = c_q * pose.translation().template cast<T>() + c_t;
}

// Between factor a -> b whose ends move with their robots' corrections C_a and C_b.
struct CoarseBetween {
  Eigen::Isometry3d T_a, T_b;
  detail::BetweenResidual between;

  template <typename T>
  bool operator()(const T* cta, const T* cqa, const T* ctb, const T* cqb, T* out) const {
    Eigen::Matrix<T, 3, 1> ta, tb;
    Eigen::Quaternion<T> qa, qb;
    moved(cta, cqa, T_a, ta, qa);
    moved(ctb, cqb, T_b, tb, qb);
    return between(ta.data(), qa.coeffs().data(), tb.data(), qb.coeffs().data(), out);
  }
};

// Prior on a pose that moves with its robot's correction.
struct CoarsePrior {
  Eigen::Isometry3d T_a;
  detail::PriorResidual prior;

  template <typename T>
  bool operator()(const T* ct, const T* cq, T* out) const {
    Eigen::Matrix<T, 3, 1> t;
    Eigen::Quaternion<T> q;
    moved(ct, cq, T_a, t, q);
    return prior(t.data(), q.coeffs().data(), out);
  }
};

Matrix6d sqrt_information(const Factor& f, Objective objective, int dimension) {
  if (objective != Objective::kSeSync || f.kind == FactorKind::kPrior) {
    return f.information.llt().matrixL().transpose();
  }
  const IsotropicWeights w = isotropic_weights(f, dimension);
  Matrix6d s = Matrix6d::Zero();
  s.diagonal() << std::sqrt(w.tau), std::sqrt(w.tau), std::sqrt(w.tau), std::sqrt(2.0 * w.kappa),
      std::sqrt(2.0 * w.kappa), std::sqrt(2.0 * w.kappa);
  return s;
}

struct Correction {
  double t[3] = {0, 0, 0};
  double q[4] = {0, 0, 0, 1};  // x, y, z, w
};

}  // namespace

std::map<uint32_t, Eigen::Isometry3d> coarse_corrections(const std::vector<Factor>& factors,
                                                         const SeparatorPoses& poses, std::optional<Key> gauge,
                                                         const SolverOptions& options, int dimension) {
  // The gauge pose is a group of its own that stays put; its robot's other poses move together.
  constexpr uint32_t kGaugeGroup = ~uint32_t{0};
  const auto group = [&](Key k) { return gauge && k == *gauge ? kGaugeGroup : robot_of(k); };
  std::map<uint32_t, Correction> c;
  // Owned here, borrowed by the problem.
  std::unique_ptr<ceres::LossFunction> robust;
  if (options.robust_loss_scale > 0) {
    robust = std::make_unique<ceres::CauchyLoss>(options.robust_loss_scale);
  }
  ceres::EigenQuaternionManifold quaternion;
  ceres::SubsetManifold planar_translation{3, {2}};
  ceres::AutoDiffManifold<detail::YawOnlyQuaternion, 4, 1> yaw_only;
  ceres::Problem::Options po;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (const Factor& f : factors) {
    const auto a = poses.find(f.a), b = poses.find(f.b);
    if (a == poses.end() || b == poses.end()) {
      continue;
    }
    if (f.kind != FactorKind::kPrior && group(f.a) == group(f.b)) {
      continue;  // unchanged by the corrections
    }
    Correction& ca = c[group(f.a)];
    const Matrix6d L = sqrt_information(f, options.objective, dimension);
    if (f.kind == FactorKind::kPrior) {
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CoarsePrior, 6, 3, 4>(
                                   new CoarsePrior{a->second, detail::PriorResidual(f.measurement, L)}),
                               nullptr, ca.t, ca.q);
    } else {
      Correction& cb = c[group(f.b)];
      problem.AddResidualBlock(new ceres::AutoDiffCostFunction<CoarseBetween, 6, 3, 4, 3, 4>(
                                   new CoarseBetween{a->second, b->second, detail::BetweenResidual(f.measurement, L)}),
                               f.robust ? robust.get() : nullptr, ca.t, ca.q, cb.t, cb.q);
    }
  }
  for (auto& [r, x] : c) {
    problem.SetManifold(x.q, dimension == 2 ? static_cast<ceres::Manifold*>(&yaw_only) : &quaternion);
    if (dimension == 2) {
      problem.SetManifold(x.t, &planar_translation);
    }
    if (r == kGaugeGroup) {
      problem.SetParameterBlockConstant(x.t);
      problem.SetParameterBlockConstant(x.q);
    }
  }
  std::map<uint32_t, Eigen::Isometry3d> out;
  if (c.empty()) {
    return out;
  }
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.function_tolerance = options.function_tolerance;
  so.initial_trust_region_radius = options.initial_trust_region_radius;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  for (const auto& [r, x] : c) {
    if (r == kGaugeGroup) {
      continue;
    }
    Eigen::Isometry3d C = Eigen::Isometry3d::Identity();
    C.linear() = Eigen::Quaterniond(x.q[3], x.q[0], x.q[1], x.q[2]).normalized().toRotationMatrix();
    C.translation() = Eigen::Vector3d(x.t[0], x.t[1], x.t[2]);
    out[r] = C;
  }
  return out;
}

}  // namespace cdc::graph
