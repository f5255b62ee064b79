// The robot-level (coarse) problem of the two-stage solve's stage 3.
#include "cdc/graph/distributed_robot.hpp"
#include "cdc/graph/objective.hpp"
#include "residuals.hpp"

#include <cmath>
#include <memory>
#include <set>
#include <utility>

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

// A coarse group: a robot's poses but the pinned ones (no key), or one pinned pose (its key).
using Group = std::pair<uint32_t, std::optional<Key>>;

// The coarse problem: one correction per group, the residuals of the factors between groups.
class CoarseProblem {
 public:
  CoarseProblem(std::optional<Key> gauge, std::set<Key> pinned, const SolverOptions& options, int dimension)
      : gauge_(gauge),
        pinned_(std::move(pinned)),
        options_(options),
        dimension_(dimension),
        problem_(problem_options()) {
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

  CoarseCorrections solve() {
    CoarseCorrections out;
    if (c_.empty()) {
      return out;
    }
    // The gauge pose stays; when no factor reaches it, its robot stays instead.
    std::optional<Group> fixed;
    if (gauge_) {
      fixed = c_.count(group(*gauge_)) != 0 ? group(*gauge_) : Group{robot_of(*gauge_), std::nullopt};
    }
    for (auto& [g, x] : c_) {
      problem_.SetManifold(x.q, dimension_ == 2 ? static_cast<ceres::Manifold*>(&yaw_only_) : &quaternion_);
      if (dimension_ == 2) {
        problem_.SetManifold(x.t, &planar_translation_);
      }
      if (g == fixed) {
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
    for (const auto& [g, x] : c_) {
      if (!g.second) {
        out.robots[g.first] = x.pose();
      } else {
        out.pinned[*g.second] = x.pose();  // the gauge's is the identity: it is held constant
      }
    }
    if (gauge_) {
      out.pinned[*gauge_] = Eigen::Isometry3d::Identity();
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
  Group group(Key k) const { return {robot_of(k), pinned_.count(k) != 0 ? std::optional<Key>(k) : std::nullopt}; }

  std::optional<Key> gauge_;
  std::set<Key> pinned_;
  SolverOptions options_;
  int dimension_;
  std::unique_ptr<ceres::LossFunction> robust_;
  ceres::EigenQuaternionManifold quaternion_;
  ceres::SubsetManifold planar_translation_{3, {2}};
  ceres::AutoDiffManifold<detail::YawOnlyQuaternion, 4, 1> yaw_only_;
  std::map<Group, Correction> c_;  // stable addresses: the problem holds pointers into them
  ceres::Problem problem_;         // declared last: destroyed before what it borrows
};

}  // namespace

Eigen::Isometry3d CoarseCorrections::of(Key key) const {
  if (auto p = pinned.find(key); p != pinned.end()) {
    return p->second;
  }
  auto r = robots.find(robot_of(key));
  return r != robots.end() ? r->second : Eigen::Isometry3d::Identity();
}

CoarseCorrections coarse_corrections(const std::vector<Factor>& factors, const SeparatorPoses& poses,
                                     std::optional<Key> gauge, const SolverOptions& options, int dimension) {
  std::set<Key> pinned;
  if (gauge) {
    pinned.insert(*gauge);
  }
  for (const Factor& f : factors) {
    if (f.kind == FactorKind::kPrior) {
      pinned.insert(f.a);
    }
  }
  CoarseProblem problem(gauge, std::move(pinned), options, dimension);
  for (const Factor& f : factors) {
    const auto a = poses.find(f.a), b = poses.find(f.b);
    if (a != poses.end() && b != poses.end()) {
      problem.add(f, a->second, b->second);
    }
  }
  return problem.solve();
}

}  // namespace cdc::graph
