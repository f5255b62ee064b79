// Conversions between IDL types and Eigen types (no PCL here: see cloud_convert.hpp).
#pragma once

#include "cdc/dds/types.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <vector>

namespace cdc::dds {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

inline Eigen::Vector3d to_eigen(const cdc_msg_Vec3& v) { return {v.x, v.y, v.z}; }
inline cdc_msg_Vec3 to_msg(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

// Message quaternion order is (x, y, z, w); Eigen's constructor takes (w, x, y, z).
inline Eigen::Quaterniond to_eigen(const cdc_msg_Quat& q) { return {q.w, q.x, q.y, q.z}; }
inline cdc_msg_Quat to_msg(const Eigen::Quaterniond& q) { return {q.x(), q.y(), q.z(), q.w()}; }

// The quaternion is normalised: callers validate first (validate.hpp) and convert after.
Eigen::Isometry3d to_eigen(const cdc_msg_Pose& pose);
cdc_msg_Pose to_msg(const Eigen::Isometry3d& T);
// Single precision (separators): rounded to float on the way out, normalised in double on the way in.
Eigen::Isometry3d to_eigen(const cdc_msg_PoseF& pose);
cdc_msg_PoseF to_msg_f(const Eigen::Isometry3d& T);

Matrix6d information_to_eigen(const cdc_msg_Information6& info);
void information_to_msg(const Matrix6d& info, cdc_msg_Information6& out);

// The body of a keyframe message: its pose in the robot's odometry frame, its pose relative to the
// keyframe before and that relative pose's information, and its cloud, lent from storage (which has to
// outlive the write, see borrow()). The caller sets the robot, the id, the incarnation and the stamp.
void keyframe_body_to_msg(const Eigen::Isometry3d& T_odom_keyframe, const Eigen::Isometry3d& T_prev,
                          const Matrix6d& information, std::vector<cdc_msg_PointXYZI>& cloud, cdc_msg_Keyframe& out);

// Wall-clock time now, integer nanoseconds since the epoch.
inline int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace cdc::dds
