// Keyframe selection: a keyframe every keyframe_distance_m or keyframe_angle_rad of odometry (the
// first at the start), carrying its pose, the relative odometry since the previous keyframe with
// an information matrix (the inverse of the registrations' covariances in between, each the
// inverse of its Hessian times keyframe_information_scale), and its deskewed cloud
// (keyframe_voxel_m voxels). The first keyframe can be held back until the next sweep, when its
// sweep's motion is known and its cloud deskewed (sent at once, it carries the sweep's motion, half a
// metre at 10 m/s, into every loop verified against it). The poses of all keyframes are kept, for
// the back-end's corrections.
#pragma once

#include "cdc/frontend/frontend_types.hpp"
#include "cdc/odometry/registration.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

namespace cdc::frontend {

class KeyframeSelector {
 public:
  explicit KeyframeSelector(const FrontendParams& params);

  // A sweep's registration, adding its uncertainty to the relative odometry since the last keyframe.
  void add_registration(const odometry::RegistrationResult& reg);
  // The keyframe this sweep (at T_odom, its deskewed cloud) gives, if any: the held first keyframe
  // goes out with the sweep after it, which cuts none. `hold`: a new keyframe is held back.
  std::optional<KeyframeOut> select(int64_t stamp_ns, const Eigen::Isometry3d& T_odom,
                                    const std::vector<Eigen::Vector3d>& deskewed, bool hold);
  // The held keyframe's cloud made again from its sweep deskewed anew.
  void redeskew_held(const std::vector<Eigen::Vector3d>& deskewed);
  bool holding() const noexcept { return held_.has_value(); }

  // Continues a robot's keyframe sequence (before the first keyframe): ids go on after `newest_id`,
  // and the first keyframe's relative odometry is to that keyframe (at T_odom_newest), with
  // `link_information`.
  void continue_after(uint32_t newest_id, const Eigen::Isometry3d& T_odom_newest, const Matrix6d& link_information);

  // A keyframe's odometry pose, if there is one with this id.
  std::optional<Eigen::Isometry3d> pose_of(uint32_t id) const;
  uint64_t count() const noexcept { return made_; }  // keyframes cut by this selector

 private:
  std::vector<Eigen::Vector3f> cloud(const std::vector<Eigen::Vector3d>& deskewed) const;
  KeyframeOut cut(int64_t stamp_ns, const Eigen::Isometry3d& T_odom, const Eigen::Isometry3d& since,
                  const std::vector<Eigen::Vector3d>& deskewed);

  FrontendParams p_;
  bool have_keyframe_ = false;
  uint32_t next_id_ = 0;
  uint64_t made_ = 0;
  std::optional<Matrix6d> link_information_;  // of the first keyframe, when continuing a sequence
  Eigen::Isometry3d T_last_keyframe_ = Eigen::Isometry3d::Identity();
  Matrix6d cov_since_keyframe_ = Matrix6d::Zero();
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses_;
  std::optional<KeyframeOut> held_;
};

}  // namespace cdc::frontend
