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

  Eigen::Isometry3d pose() const {
    Eigen::Isometry3d C = Eigen::Isometry3d::Identity();
    C.linear() = Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix();
    C.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    return C;
  }
};

// The gauge pose is a group of its own that stays put; its robot's other poses move together.
constexpr uint32_t kGaugeGroup = ~uint32_t{0};

// The coarse problem: one correction per group, the residuals of the factors between groups.
class CoarseProblem {
 public:
  CoarseProblem(std::optional<Key> gauge, const SolverOptions& options, int dimension)
      : gauge_(gauge), options_(options), dimension_(dimension), problem_(problem_options()) {
    if (options.robust_loss_scale > 0) {
      robust_ = std::make_unique<ceres::CauchyLoss>(options.robust_loss_scale);
    }
  }

  void add(const Factor& f, const Eigen::Isometry3d& T_a, const Eigen::Isometry3d& T_b) {
    if (f.kind != FactorKind::kPrior && group(f.a) == group(f.b)) {
      return;  // unchanged by the corrections
    }
    Correction& ca = c_[group(f.a)];
    const Matrix6d L = sqrt_information(f, options_.objective, dimension_);
    if (f.kind == FactorKind::kPrior) {
      problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<CoarsePrior, 6, 3, 4>(
                                    new CoarsePrior{T_a, detail::PriorResidual(f.measurement, L)}),
                                nullptr, ca.t, ca.q);
      return;
    }
    Correction& cb = c_[group(f.b)];
    problem_.AddResidualBlock(new ceres::AutoDiffCostFunction<CoarseBetween, 6, 3, 4, 3, 4>(
                                  new CoarseBetween{T_a, T_b, detail::BetweenResidual(f.measurement, L)}),
                              f.robust ? robust_.get() : nullptr, ca.t, ca.q, cb.t, cb.q);
  }

  std::map<uint32_t, Eigen::Isometry3d> solve() {
    std::map<uint32_t, Eigen::Isometry3d> out;
    if (c_.empty()) {
      return out;
    }
    // The gauge group stays; when no factor reaches the gauge pose, its robot stays instead.
    const uint32_t fixed = c_.count(kGaugeGroup) != 0 || !gauge_ ? kGaugeGroup : robot_of(*gauge_);
    for (auto& [r, x] : c_) {
      problem_.SetManifold(x.q, dimension_ == 2 ? static_cast<ceres::Manifold*>(&yaw_only_) : &quaternion_);
      if (dimension_ == 2) {
        problem_.SetManifold(x.t, &planar_translation_);
      }
      if (r == fixed) {
        problem_.SetParameterBlockConstant(x.t);
        problem_.SetParameterBlockConstant(x.q);
      }
    }
    ceres::Solver::Options so;
    so.linear_solver_type = ceres::DENSE_QR;
    so.max_num_iterations = options_.max_iterations;
    so.function_tolerance = options_.function_tolerance;
    so.initial_trust_region_radius = options_.initial_trust_region_radius;
    so.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(so, &problem_, &summary);
    for (const auto& [r, x] : c_) {
      if (r != kGaugeGroup) {
        out[r] = x.pose();
      }
    }
    return out;
  }

 private:
  static ceres::Problem::Options problem_options() {
    ceres::Problem::Options po;  // the loss and the manifolds are owned here, borrowed by the problem
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    return po;
  }
  uint32_t group(Key k) const { return gauge_ && k == *gauge_ ? kGaugeGroup : robot_of(k); }

  std::optional<Key> gauge_;
  SolverOptions options_;
  int dimension_;
  std::unique_ptr<ceres::LossFunction> robust_;
  ceres::EigenQuaternionManifold quaternion_;
  ceres::SubsetManifold planar_translation_{3, {2}};
  ceres::AutoDiffManifold<detail::YawOnlyQuaternion, 4, 1> yaw_only_;
  std::map<uint32_t, Correction> c_;  // stable addresses: the problem holds pointers into them
  ceres::Problem problem_;            // declared last: destroyed before what it borrows
};

}  // namespace

std::map<uint32_t, Eigen::Isometry3d> coarse_corrections(const std::vector<Factor>& factors,
                                                         const SeparatorPoses& poses, std::optional<Key> gauge,
                                                         const SolverOptions& options, int dimension) {
  CoarseProblem problem(gauge, options, dimension);
  for (const Factor& f : factors) {
    const auto a = poses.find(f.a), b = poses.find(f.b);
    if (a != poses.end() && b != poses.end()) {
      problem.add(f, a->second, b->second);
    }
  }
  return problem.solve();
}

}  // namespace cdc::graph
