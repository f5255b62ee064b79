// Least-squares alignment of two point sets (Umeyama 1991; Horn's closed form for rotation).
#pragma once

#include <Eigen/Geometry>

namespace cdc::geometry {

struct Alignment {
  Eigen::Isometry3d T_dst_src = Eigen::Isometry3d::Identity();  // rotation and translation
  double scale = 1.0;  // dst ~= scale * R * src + t
  bool ok = false;     // false when the points are too few or degenerate
};

// Finds s, R, t minimising sum |dst_i - (s R src_i + t)|^2; scale stays 1 unless with_scale.
// src and dst are 3xN with N >= 3 non-collinear points (N >= 1 gives translation only).
Alignment align_umeyama(const Eigen::Matrix3Xd& src, const Eigen::Matrix3Xd& dst, bool with_scale);

// Applies an alignment to a pose: position s R p + t, orientation R * R_p.
Eigen::Isometry3d apply(const Alignment& a, const Eigen::Isometry3d& pose);

}  // namespace cdc::geometry
