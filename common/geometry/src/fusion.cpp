#include "cdc/geometry/fusion.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>

namespace cdc::geometry {

FusionResult fuse_pose(const Eigen::Isometry3d& current, const Eigen::Isometry3d& target, const FusionThresholds& t) {
  FusionResult r;
  r.diff_pos = (target.translation() - current.translation()).norm();
  r.diff_rot = rotation_angle(current.rotation().transpose() * target.rotation());
  const double posscale = r.diff_pos > t.pos_max ? t.pos_max / r.diff_pos : 1.0;  // eq. 10
  const double rotscale = r.diff_rot > t.rot_max ? t.rot_max / r.diff_rot : 1.0;  // eq. 11
  r.lambda = std::min(posscale, rotscale);                                        // eq. 12
  r.fused = interpolate(current, target, r.lambda);                               // eq. 13, 14
  return r;
}

}  // namespace cdc::geometry
