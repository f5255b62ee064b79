#include "cdc/dds/convert.hpp"

namespace cdc::dds {

Eigen::Isometry3d to_eigen(const cdc_msg_Pose& pose) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = to_eigen(pose.orientation).normalized().toRotationMatrix();
  T.translation() = to_eigen(pose.position);
  return T;
}

cdc_msg_Pose to_msg(const Eigen::Isometry3d& T) {
  cdc_msg_Pose p{};
  p.position = to_msg(Eigen::Vector3d(T.translation()));
  Eigen::Quaterniond q(T.rotation());
  q.normalize();
  p.orientation = to_msg(q);
  return p;
}

Eigen::Isometry3d to_eigen(const cdc_msg_PoseF& pose) {
  const cdc_msg_Quatf& q = pose.orientation;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(q.w, q.x, q.y, q.z).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return T;
}

cdc_msg_PoseF to_msg_f(const Eigen::Isometry3d& T) {
  const Eigen::Vector3f p = T.translation().cast<float>();
  const Eigen::Quaternionf q = Eigen::Quaterniond(T.rotation()).normalized().cast<float>();
  return cdc_msg_PoseF{{p.x(), p.y(), p.z()}, {q.x(), q.y(), q.z(), q.w()}};
}

Matrix6d information_to_eigen(const cdc_msg_Information6& info) {
  Matrix6d m;
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      m(r, c) = info[r * 6 + c];
    }
  }
  return m;
}

void information_to_msg(const Matrix6d& info, cdc_msg_Information6& out) {
  for (int r = 0; r < 6; ++r) {
    for (int c = 0; c < 6; ++c) {
      out[r * 6 + c] = info(r, c);
    }
  }
}

void keyframe_body_to_msg(const Eigen::Isometry3d& T_odom_keyframe, const Eigen::Isometry3d& T_prev,
                          const Matrix6d& information, std::vector<cdc_msg_PointXYZI>& cloud, cdc_msg_Keyframe& out) {
  out.T_odom_keyframe = to_msg(T_odom_keyframe);
  out.T_prev_keyframe = to_msg(T_prev);
  information_to_msg(information, out.information);
  out.point_count = static_cast<uint32_t>(cloud.size());
  borrow(out.cloud, cloud);
}

}  // namespace cdc::dds
