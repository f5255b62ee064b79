// Over-relaxed pose update shared by the distributed solvers.
#pragma once

#include <Eigen/Geometry>

#include <algorithm>

namespace cdc::graph::detail {

// Moves `from` towards `to` by the factor g (translation linearly, rotation along the geodesic);
// returns the moved pose and sets *change to the larger of the distance moved [m] and the angle [rad].
inline Eigen::Isometry3d relax_pose(const Eigen::Isometry3d& from, const Eigen::Isometry3d& to, double g,
                                    double* change) {
  Eigen::Isometry3d next = Eigen::Isometry3d::Identity();
  next.translation() = from.translation() + g * (to.translation() - from.translation());
  const Eigen::AngleAxisd step(from.rotation().transpose() * to.rotation());
  next.linear() = from.rotation() * Eigen::AngleAxisd(g * step.angle(), step.axis()).toRotationMatrix();
  *change = std::max((next.translation() - from.translation()).norm(), g * step.angle());
  return next;
}

}  // namespace cdc::graph::detail
