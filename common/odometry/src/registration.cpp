// The registration's shared parts: the settings' GICP preset, the choice of method for plain
// clouds, one Gauss-Newton step's bookkeeping, and the judging of a result.
#include "cdc/odometry/registration.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/normals.hpp"
#include "kdtree.hpp"
#include "registration_detail.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <cmath>
#include <string>

namespace cdc::odometry {

RegistrationSettings RegistrationSettings::gicp() {
  RegistrationSettings s;
  s.method = RegistrationMethod::kGicp;
  s.max_iterations = 64;
  s.max_correspondence_m = 1.0;
  s.translation_eps_m = 1e-5;
  s.rotation_eps_rad = 1e-6;
  s.voxel_m = 0.1;
  s.neighbours = 10;
  return s;
}

RegistrationResult register_clouds(const std::vector<Eigen::Vector3d>& source,
                                   const std::vector<Eigen::Vector3d>& target, const Eigen::Isometry3d& initial,
                                   const RegistrationSettings& s) {
  if (s.method == RegistrationMethod::kGicp) {
    return register_gicp(PreparedCloud(source, s), PreparedCloud(target, s), initial, s);
  }
  return detail::register_point_to_plane(source, target, initial, s);
}

namespace detail {

bool gauss_newton_step(const Matrix6d& H, const Eigen::Matrix<double, 6, 1>& b, int n, double sum2, int it,
                       const RegistrationSettings& s, RegistrationResult& out) {
  out.correspondences = n;
  out.iterations = it + 1;
  out.hessian = H;
  out.rmse = n > 0 ? std::sqrt(sum2 / n) : 0;
  if (n < 20) {
    out.warnings.push_back("iteration " + std::to_string(it + 1) + ": " + std::to_string(n) +
                           " correspondences, 20 needed");
    return false;
  }
  const Eigen::Matrix<double, 6, 1> dx = H.ldlt().solve(-b);
  if (!dx.allFinite()) {
    out.warnings.push_back("iteration " + std::to_string(it + 1) + ": the update is not finite");
    return false;
  }
  out.T_target_source = out.T_target_source * geometry::se3_exp(dx);
  if (dx.head<3>().norm() < s.translation_eps_m && dx.tail<3>().norm() < s.rotation_eps_rad) {
    out.converged = true;
    return false;
  }
  return true;
}

void at_iteration_limit(const RegistrationSettings& s, RegistrationResult& out) {
  if (out.correspondences < 20) {
    out.warnings.push_back("no iteration ran (max_iterations " + std::to_string(s.max_iterations) + ")");
    return;
  }
  out.converged = true;
  out.warnings.push_back("stopped at max_iterations (" + std::to_string(s.max_iterations) +
                         ") with the update still above the eps");
}

void judge_overlap(const std::vector<double>& distances, double inlier_m, RegistrationResult& r) {
  double sum = 0;
  size_t inliers = 0;
  for (const double d : distances) {
    if (d <= inlier_m) {
      sum += d * d;
      ++inliers;
    }
  }
  r.overlap = distances.empty() ? 0.0 : static_cast<double>(inliers) / static_cast<double>(distances.size());
  r.fitness = inliers > 0 ? sum / static_cast<double>(inliers) : 1e9;
}

void judge_information(double scale, RegistrationResult& r) {
  // The graph's residual takes the translation in the target's frame: rotate that block.
  Matrix6d J = Matrix6d::Identity();
  J.topLeftCorner<3, 3>() = r.T_target_source.rotation();
  const Matrix6d H = 0.5 * (r.hessian + r.hessian.transpose());
  const Matrix6d info = scale * (J * H * J.transpose());
  if (info.allFinite() && Eigen::SelfAdjointEigenSolver<Matrix6d>(info).eigenvalues()(0) > 0) {
    r.information = 0.5 * (info + info.transpose());
  } else {
    r.converged = false;
    r.warnings.emplace_back("the information is not positive definite: a direction is unconstrained");
  }
}

}  // namespace detail

AlignmentScore score_alignment(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                               const Eigen::Isometry3d& T_target_source, double voxel_m, double max_distance_m) {
  const std::vector<Eigen::Vector3d> src = voxel_filter(source, voxel_m), tgt = voxel_filter(target, voxel_m);
  const std::vector<Eigen::Vector3d> normals = knn_normals(tgt, tgt, 10, 1.0);
  detail::CloudAdaptor adaptor{&tgt};
  const detail::KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));  // built by its constructor
  AlignmentScore out;
  double sum2 = 0;
  for (const Eigen::Vector3d& p : src) {
    const Eigen::Vector3d q = T_target_source * p;
    size_t j = 0;
    double d2 = 0;
    if (tree.knnSearch(q.data(), 1, &j, &d2) < 1 || d2 > max_distance_m * max_distance_m) continue;
    if (normals[j].squaredNorm() < 0.5) continue;  // not on a plane
    const double r = normals[j].dot(q - tgt[j]);
    sum2 += r * r;
    ++out.matched;
    if (std::abs(r) <= 0.01) ++out.within_1cm;
    if (std::abs(r) <= 0.02) ++out.within_2cm;
  }
  out.source_points = src.size();
  out.rms_point_to_plane_m = out.matched > 0 ? std::sqrt(sum2 / static_cast<double>(out.matched)) : 0.0;
  return out;
}

}  // namespace cdc::odometry
