#include "cdc/frontend/correction_fusion.hpp"

#include "cdc/geometry/se3.hpp"

namespace cdc::frontend {

CorrectionFusion::CorrectionFusion(const FrontendParams& params) : p_(params) {}

bool CorrectionFusion::set_correction(const Eigen::Isometry3d& T_odom_keyframe,
                                      const Eigen::Isometry3d& T_world_keyframe, const Eigen::Isometry3d& T_world_robot,
                                      bool levelled) {
  // The keyframe's corrected pose in the odometry frame, and the map from raw to corrected odometry.
  const Eigen::Isometry3d corrected = T_world_robot.inverse() * T_world_keyframe;
  Eigen::Isometry3d C = corrected * T_odom_keyframe.inverse();
  const bool hold = p_.correction_holds_tilt && levelled;
  if (hold) {
    // Levelled: keep the correction's turn about the vertical, and move the keyframe to its
    // corrected position with it.
    const Eigen::Quaterniond yaw = geometry::twist_about(Eigen::Quaterniond(C.rotation()), Eigen::Vector3d::UnitZ());
    C.linear() = yaw.toRotationMatrix();
    C.translation() = corrected.translation() - yaw * T_odom_keyframe.translation();
  }
  correction_ = C;
  T_world_robot_ = T_world_robot;
  return hold;
}

CorrectionFusion::Fused CorrectionFusion::fuse(const Eigen::Isometry3d& increment, const Eigen::Isometry3d& T_odom) {
  Fused out;
  if (correction_) {
    const geometry::FusionResult f = geometry::fuse_pose(published_ * increment, *correction_ * T_odom, p_.fusion);
    published_ = f.fused;
    out.lambda = f.lambda;
  } else {
    published_ = T_odom;
  }
  out.T_odom_base = published_;
  if (T_world_robot_) out.T_world_base = *T_world_robot_ * published_;
  return out;
}

}  // namespace cdc::frontend
