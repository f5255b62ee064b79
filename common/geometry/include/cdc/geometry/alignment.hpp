// Least-squares alignment of two point sets (Umeyama 1991; Horn's closed form for rotation).
#pragma once

#include <Eigen/Geometry>

#include <utility>
#include <vector>

namespace cdc::geometry {

struct Alignment {
  Eigen::Isometry3d T_dst_src = Eigen::Isometry3d::Identity();  // rotation and translation
  double scale = 1.0;                                           // dst ~= scale * R * src + t
  bool ok = false;                                              // false when the points are too few or degenerate
};

// Finds s, R, t minimising sum |dst_i - (s R src_i + t)|^2; scale stays 1 unless with_scale.
// src and dst are 3xN with N >= 3 non-collinear points (N >= 1 gives translation only).
Alignment align_umeyama(const Eigen::Matrix3Xd& src, const Eigen::Matrix3Xd& dst, bool with_scale);

// Applies an alignment to a pose: position s R p + t, orientation R * R_p.
Eigen::Isometry3d apply(const Alignment& a, const Eigen::Isometry3d& pose);

// The rigid transform T that best maps poses a_i onto poses b_i (b_i ~= T * a_i), positions and
// orientations together: each pair adds its position and the three points `arm_m` along its axes to a
// Umeyama fit, so a single pair gives b_0 * a_0^-1 exactly and a straight trajectory is not degenerate.
// Empty input or arm_m <= 0 gives ok = false.
Alignment align_poses(const std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>>& a_b, double arm_m = 1.0);

// align_poses over a stream of pairs: add() keeps only the sums the fit needs (means and the
// cross-covariance), so fitting n pairs takes O(n) time and O(1) memory, without a copy of the points.
class PoseAligner {
 public:
  explicit PoseAligner(double arm_m = 1.0) : arm_m_(arm_m) {}
  void add(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);
  size_t pairs() const noexcept { return pairs_; }
  // The rigid fit of b_i ~= T * a_i; ok = false with no pairs or arm_m <= 0.
  Alignment solve() const;

 private:
  void add_point(const Eigen::Vector3d& src, const Eigen::Vector3d& dst);
  double arm_m_;
  size_t pairs_ = 0;
  double points_ = 0.0;
  Eigen::Vector3d sum_src_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_dst_ = Eigen::Vector3d::Zero();
  Eigen::Matrix3d sum_dst_src_ = Eigen::Matrix3d::Zero();  // sum of dst * src^T
};

}  // namespace cdc::geometry
