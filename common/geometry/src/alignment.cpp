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
  PoseAligner aligner(arm_m);
  for (const auto& [a, b] : a_b) aligner.add(a, b);
  return aligner.solve();
}

void PoseAligner::add_point(const Eigen::Vector3d& src, const Eigen::Vector3d& dst) {
  points_ += 1.0;
  sum_src_ += src;
  sum_dst_ += dst;
  sum_dst_src_ += dst * src.transpose();
}

void PoseAligner::add(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  ++pairs_;
  add_point(a.translation(), b.translation());
  for (int axis = 0; axis < 3; ++axis) {
    add_point(a * (arm_m_ * Eigen::Vector3d::Unit(axis)), b * (arm_m_ * Eigen::Vector3d::Unit(axis)));
  }
}

// Umeyama's rigid fit from the sums: the centred cross-covariance is sum(d s^T) / n - mu_d mu_s^T.
Alignment PoseAligner::solve() const {
  Alignment out;
  if (pairs_ == 0 || !(arm_m_ > 0.0)) {
    return out;
  }
  const Eigen::Vector3d mu_src = sum_src_ / points_;
  const Eigen::Vector3d mu_dst = sum_dst_ / points_;
  const Eigen::Matrix3d sigma = sum_dst_src_ / points_ - mu_dst * mu_src.transpose();
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(sigma, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Vector3d sv = svd.singularValues();
  if (sv(1) < 1e-12 * std::max(1.0, sv(0))) {
    return out;
  }
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0.0) {
    S(2, 2) = -1.0;
  }
  const Eigen::Matrix3d R = svd.matrixU() * S * svd.matrixV().transpose();
  out.T_dst_src.linear() = R;
  out.T_dst_src.translation() = mu_dst - R * mu_src;
  out.ok = true;
  return out;
}

}  // namespace cdc::geometry
