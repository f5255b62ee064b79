#include "cdc/graph/objective.hpp"

#include <Eigen/LU>

namespace cdc::graph {

IsotropicWeights isotropic_weights(const Factor& f, int dimension) {
  IsotropicWeights w;
  if (dimension == 2) {
    const Eigen::Matrix2d tt = f.information.topLeftCorner<2, 2>();
    w.tau = 2.0 / tt.inverse().trace();
    w.kappa = f.information(5, 5);
  } else {
    const Eigen::Matrix3d tt = f.information.topLeftCorner<3, 3>();
    const Eigen::Matrix3d rr = f.information.bottomRightCorner<3, 3>();
    w.tau = 3.0 / tt.inverse().trace();
    w.kappa = 3.0 / (2.0 * rr.inverse().trace());
  }
  return w;
}

double sesync_objective(const PoseGraph& graph) {
  double f = 0.0;
  for (const Factor& e : graph.factors) {
    if (e.kind == FactorKind::kPrior) {
      continue;
    }
    const Eigen::Isometry3d& Ti = graph.poses.at(e.a);
    const Eigen::Isometry3d& Tj = graph.poses.at(e.b);
    const IsotropicWeights w = isotropic_weights(e, graph.dimension);
    const Eigen::Matrix3d dR = Tj.rotation() - Ti.rotation() * e.measurement.rotation();
    const Eigen::Vector3d dt = Tj.translation() - Ti.translation() - Ti.rotation() * e.measurement.translation();
    f += w.kappa * dR.squaredNorm() + w.tau * dt.squaredNorm();
  }
  return f;
}

double squared_residual(const PoseGraph& graph, const Factor& e) {
  const Eigen::Isometry3d& Ta = graph.poses.at(e.a);
  Eigen::Isometry3d est = Ta;  // prior: T_world_a
  if (e.kind != FactorKind::kPrior) {
    est = Ta.inverse() * graph.poses.at(e.b);
  }
  const Eigen::Quaterniond q_err(e.measurement.rotation().transpose() * est.rotation());
  Eigen::Matrix<double, 6, 1> r;
  r.head<3>() = est.translation() - e.measurement.translation();
  const Eigen::Vector3d v = q_err.vec();
  r.tail<3>() = 2.0 * (q_err.w() < 0 ? Eigen::Vector3d(-v) : v);
  return r.dot(e.information * r);
}

double full_information_cost(const PoseGraph& graph) {
  double f = 0.0;
  for (const Factor& e : graph.factors) f += squared_residual(graph, e);
  return f;
}

}  // namespace cdc::graph
