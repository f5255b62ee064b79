#include "cdc/frontend/keyframe_selection.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <algorithm>

namespace cdc::frontend {

KeyframeSelector::KeyframeSelector(const FrontendParams& params) : p_(params) {}

void KeyframeSelector::add_registration(const odometry::RegistrationResult& reg) {
  if (reg.correspondences <= 0) return;
  const Matrix6d info_step = reg.hessian * p_.keyframe_information_scale;
  const Eigen::LDLT<Matrix6d> ldlt(info_step);
  if (ldlt.info() == Eigen::Success) cov_since_keyframe_ += ldlt.solve(Matrix6d::Identity());
}

std::optional<KeyframeOut> KeyframeSelector::select(int64_t stamp_ns, const Eigen::Isometry3d& T_odom,
                                                    const std::vector<Eigen::Vector3d>& deskewed, bool hold) {
  const Eigen::Isometry3d since = T_last_keyframe_.inverse() * T_odom;
  if (held_) {
    std::optional<KeyframeOut> k = std::move(held_);
    held_.reset();
    return k;
  }
  const bool far = !have_keyframe_ || since.translation().norm() >= p_.keyframe_distance_m ||
                   geometry::rotation_angle(since.rotation()) >= p_.keyframe_angle_rad;
  if (!far) return std::nullopt;
  KeyframeOut k = cut(stamp_ns, T_odom, since, deskewed);
  if (hold) {
    held_ = std::move(k);
    return std::nullopt;
  }
  return k;
}

KeyframeOut KeyframeSelector::cut(int64_t stamp_ns, const Eigen::Isometry3d& T_odom, const Eigen::Isometry3d& since,
                                  const std::vector<Eigen::Vector3d>& deskewed) {
  KeyframeOut k;
  k.id = next_id_++;
  ++made_;
  k.stamp_ns = stamp_ns;
  k.T_odom_keyframe = T_odom;
  k.T_prev = have_keyframe_ || link_information_ ? since : Eigen::Isometry3d::Identity();
  Matrix6d cov = cov_since_keyframe_;
  cov.diagonal().array() += 1e-8;
  if (have_keyframe_) {
    k.information = cov.inverse();
  } else {
    k.information = link_information_.value_or(Matrix6d::Identity() * 1e6);
  }
  k.information = 0.5 * (k.information + k.information.transpose());
  k.cloud = cloud(deskewed);
  poses_.emplace_back(k.id, T_odom);
  T_last_keyframe_ = T_odom;
  cov_since_keyframe_.setZero();
  have_keyframe_ = true;
  return k;
}

void KeyframeSelector::continue_after(uint32_t newest_id, const Eigen::Isometry3d& T_odom_newest,
                                      const Matrix6d& link_information) {
  next_id_ = newest_id + 1;
  T_last_keyframe_ = T_odom_newest;
  link_information_ = link_information;
  poses_.emplace_back(newest_id, T_odom_newest);  // a correction naming it applies at once
}

void KeyframeSelector::redeskew_held(const std::vector<Eigen::Vector3d>& deskewed) {
  if (held_) held_->cloud = cloud(deskewed);
}

std::optional<Eigen::Isometry3d> KeyframeSelector::pose_of(uint32_t id) const {
  const auto it = std::find_if(poses_.begin(), poses_.end(), [&](const auto& k) { return k.first == id; });
  if (it == poses_.end()) return std::nullopt;
  return it->second;
}

std::vector<Eigen::Vector3f> KeyframeSelector::cloud(const std::vector<Eigen::Vector3d>& deskewed) const {
  std::vector<Eigen::Vector3f> out;
  for (const auto& p : odometry::voxel_filter(deskewed, p_.keyframe_voxel_m)) out.push_back(p.cast<float>());
  return out;
}

}  // namespace cdc::frontend
