// Gravity levelling (FrontendParams::level_with_gravity): the registered pose turned into a frame
// whose roll and pitch do not follow the map's tilt. The IMU window's gravity (map frame) passes
// through a linear-trend filter (level_gain, level_trend_gain): it follows a steadily drifting tilt
// without lag and averages the estimate's sweep-to-sweep noise. Its direction level_reference_sweeps
// sweeps after the window first ran is the reference; the levelling rotation takes the filtered
// gravity back to it. The registered increments are composed in the levelled frame.
#pragma once

#include "cdc/frontend/frontend_types.hpp"

#include <Eigen/Geometry>

#include <optional>

namespace cdc::frontend {

class GravityLeveller {
 public:
  explicit GravityLeveller(const FrontendParams& params);

  // The registered pose T (map frame) in the levelled frame, from the previous sweep's registered
  // (T_last) and levelled (T_out_last) poses; `gravity`: the running window's estimate for this
  // sweep (none: the levelling rotation stays). Off, T as it is.
  Eigen::Isometry3d level(const Eigen::Isometry3d& T, const Eigen::Isometry3d& T_last,
                          const Eigen::Isometry3d& T_out_last, const std::optional<Eigen::Vector3d>& gravity);

  // The reference is known: the odometry is levelled from now on.
  bool reference_known() const noexcept { return reference_.has_value(); }
  // The levelling rotation now and its largest so far [deg].
  double angle_deg() const noexcept { return angle_deg_; }
  double max_angle_deg() const noexcept { return max_angle_deg_; }

 private:
  void observe(const Eigen::Vector3d& gravity);

  FrontendParams p_;
  Eigen::Quaterniond level_ = Eigen::Quaterniond::Identity();  // map frame -> odometry frame (tilt)
  std::optional<Eigen::Vector3d> reference_, smoothed_;        // map frame, unit
  Eigen::Vector3d trend_ = Eigen::Vector3d::Zero();
  size_t sweeps_ = 0;
  double angle_deg_ = 0, max_angle_deg_ = 0;
};

}  // namespace cdc::frontend
