// Correction fusion (the adaptive pose fusion of CDC-SLAM eq. 8-14): the published pose follows
// the odometry's own increment and is pulled towards the corrected pose by at most the fusion
// thresholds per sweep, so that it never jumps. A back-end correction for a keyframe maps the raw
// odometry onto the corrected odometry frame (T_world_robot^-1 T_world_keyframe against the
// keyframe's raw pose); with the odometry levelled and correction_holds_tilt, only its turn about
// the vertical is taken, the keyframe moved to its corrected position.
#pragma once

#include "cdc/frontend/frontend_types.hpp"
#include "cdc/geometry/fusion.hpp"

#include <Eigen/Geometry>

#include <optional>

namespace cdc::frontend {

class CorrectionFusion {
 public:
  explicit CorrectionFusion(const FrontendParams& params);

  // A back-end result for a keyframe whose raw odometry is T_odom_keyframe: its optimised pose in
  // the world and T_world_robot. `levelled`: the odometry is levelled with gravity. True when only
  // the correction's turn about the vertical was taken.
  bool set_correction(const Eigen::Isometry3d& T_odom_keyframe, const Eigen::Isometry3d& T_world_keyframe,
                      const Eigen::Isometry3d& T_world_robot, bool levelled);

  struct Fused {
    Eigen::Isometry3d T_odom_base = Eigen::Isometry3d::Identity();  // published, odometry frame
    std::optional<Eigen::Isometry3d> T_world_base;                  // once T_world_robot is known
    double lambda = 1.0;                                            // eq. 12 (1: no limit)
  };
  // The published pose for a sweep whose odometry is T_odom, `increment` after the previous one's.
  Fused fuse(const Eigen::Isometry3d& increment, const Eigen::Isometry3d& T_odom);

 private:
  FrontendParams p_;
  Eigen::Isometry3d published_ = Eigen::Isometry3d::Identity();
  std::optional<Eigen::Isometry3d> correction_;  // maps raw odometry to the corrected odometry frame
  std::optional<Eigen::Isometry3d> T_world_robot_;
};

}  // namespace cdc::frontend
