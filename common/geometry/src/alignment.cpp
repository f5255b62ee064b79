#include "cdc/geometry/alignment.hpp"

#include <Eigen/SVD>

namespace cdc::geometry {

Alignment align_umeyama(const Eigen::Matrix3Xd& src, const Eigen::Matrix3Xd& dst, bool with_scale) {
  Alignment out;
  const Eigen::Index n = src.cols();
  if (n == 0 || dst.cols() != n) {
    return out;
  }
  const Eigen::Vector3d mu_src = src.rowwise().mean();
  const Eigen::Vector3d mu_dst = dst.rowwise().mean();
  const Eigen::Matrix3Xd xs = src.colwise() - mu_src;
  const Eigen::Matrix3Xd xd = dst.colwise() - mu_dst;
  const double var_src = xs.squaredNorm() / static_cast<double>(n);

  if (n < 3) {  // translation only
    out.T_dst_src.translation() = mu_dst - mu_src;
    out.ok = true;
    return out;
  }

  // Cross-covariance of the centred sets; its SVD gives the optimal rotation (Umeyama eq. 38-41).
  const Eigen::Matrix3d sigma = xd * xs.transpose() / static_cast<double>(n);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (sv(1) < 1e-12 * std::max(1.0, sv(0))) {  // collinear: rotation about the line is undetermined
    return out;
  }
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) {
    S(2, 2) = -1.0;
  }
  const Eigen::Matrix3d R = svd.matrixU() * S * svd.matrixV().transpose();
  double scale = 1.0;
  if (with_scale) {
    if (var_src <= 0.0) {
      return out;
    }
    scale = (sv.asDiagonal() * S).trace() / var_src;
  }
  out.T_dst_src.linear() = R;
  out.T_dst_src.translation() = mu_dst - scale * R * mu_src;
  out.scale = scale;
  out.ok = true;
  return out;
}

Eigen::Isometry3d apply(const Alignment& a, const Eigen::Isometry3d& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = a.T_dst_src.rotation() * pose.rotation();
  out.translation() = a.scale * (a.T_dst_src.rotation() * pose.translation()) + a.T_dst_src.translation();
  return out;
}

Alignment align_poses(const std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>>& a_b, double arm_m) {
  if (a_b.empty() || !(arm_m > 0.0)) {
    return Alignment{};
  }
  const Eigen::Index n = static_cast<Eigen::Index>(a_b.size()) * 4;
  Eigen::Matrix3Xd src(3, n), dst(3, n);
  Eigen::Index c = 0;
  for (const auto& [a, b] : a_b) {
    src.col(c) = a.translation();
    dst.col(c++) = b.translation();
    for (int axis = 0; axis < 3; ++axis) {
      src.col(c) = a * (arm_m * Eigen::Vector3d::Unit(axis));
      dst.col(c++) = b * (arm_m * Eigen::Vector3d::Unit(axis));
    }
  }
  return align_umeyama(src, dst, false);
}

}  // namespace cdc::geometry
