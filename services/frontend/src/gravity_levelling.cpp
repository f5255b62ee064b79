#include "cdc/frontend/gravity_levelling.hpp"

#include <algorithm>
#include <cmath>

namespace cdc::frontend {

GravityLeveller::GravityLeveller(const FrontendParams& params) : p_(params) {}

Eigen::Isometry3d GravityLeveller::level(const Eigen::Isometry3d& T, const Eigen::Isometry3d& T_last,
                                         const Eigen::Isometry3d& T_out_last,
                                         const std::optional<Eigen::Vector3d>& gravity) {
  if (!p_.level_with_gravity) return T;
  if (gravity) observe(*gravity);
  // The registered increment, turned into the levelled frame; the orientation turned likewise.
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = level_.toRotationMatrix() * T.linear();
  out.translation() = T_out_last.translation() + level_ * (T.translation() - T_last.translation());
  return out;
}

void GravityLeveller::observe(const Eigen::Vector3d& gravity) {
  const Eigen::Vector3d g = gravity.normalized();
  if (!smoothed_) {
    smoothed_ = g;
    trend_.setZero();
  }
  const Eigen::Vector3d predicted = *smoothed_ + trend_;
  smoothed_ = (predicted + p_.level_gain * (g - predicted)).normalized();
  trend_ += p_.level_trend_gain * (g - predicted);
  if (!reference_) {
    if (++sweeps_ >= p_.level_reference_sweeps) reference_ = *smoothed_;
    return;
  }
  level_ = Eigen::Quaterniond::FromTwoVectors(*smoothed_, *reference_);
  angle_deg_ = Eigen::AngleAxisd(level_).angle() * 180.0 / M_PI;
  max_angle_deg_ = std::max(max_angle_deg_, angle_deg_);
}

}  // namespace cdc::frontend
