// Adaptive pose fusion with a dynamically scaled correction factor (CDC-SLAM paper, eq. 8-14):
// a pose moves toward a target by at most pos_max in translation and rot_max in rotation per
// application, so corrections never make a trajectory jump.
#pragma once

#include <Eigen/Geometry>

namespace cdc::geometry {

struct FusionThresholds {
  double pos_max = 0.10;  // [m] largest translation step per fusion
  double rot_max = 0.02;  // [rad] largest rotation step per fusion
};

struct FusionResult {
  Eigen::Isometry3d fused = Eigen::Isometry3d::Identity();
  double lambda = 1.0;    // min(posscale, rotscale), eq. 12
  double diff_pos = 0.0;  // [m], eq. 8
  double diff_rot = 0.0;  // [rad], eq. 9
};

// Blends `current` toward `target`: position linearly (eq. 13), rotation by slerp (eq. 14, with
// the first weight sin((1 - lambda) theta) / sin theta).
FusionResult fuse_pose(const Eigen::Isometry3d& current, const Eigen::Isometry3d& target, const FusionThresholds& t);

}  // namespace cdc::geometry
