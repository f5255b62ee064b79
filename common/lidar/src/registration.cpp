// Loop verification's registration: the odometry library's generalized ICP (one implementation in
// the project) from the caller's guess, judged by fitness and overlap over nearest neighbours.
#include "cdc/lidar/registration.hpp"

#include "cdc/odometry/pair_registration.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>

namespace cdc::lidar {
namespace {

std::vector<Eigen::Vector3d> to_double(const std::vector<Eigen::Vector3f>& pts) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back(p.cast<double>());
  return out;
}

std::vector<Eigen::Vector3d> reduced(const std::vector<Eigen::Vector3f>& pts, double voxel_m) {
  std::vector<Eigen::Vector3d> d = to_double(pts);
  return voxel_m > 0 ? odometry::voxel_centroids(d, voxel_m) : d;
}

}  // namespace

std::vector<Eigen::Vector3f> voxel_downsample(const std::vector<Eigen::Vector3f>& points, double voxel_m) {
  std::vector<Eigen::Vector3f> out;
  const std::vector<Eigen::Vector3d> c = reduced(points, voxel_m);
  out.reserve(c.size());
  for (const auto& p : c) out.push_back(p.cast<float>());
  return out;
}

PreparedCloud::PreparedCloud(const std::vector<Eigen::Vector3f>& points, const RegistrationParams& p)
    : gicp_(std::make_shared<const odometry::GicpCloud>(reduced(points, p.voxel_m), p.neighbours)) {}

size_t PreparedCloud::size() const { return gicp_->points().size(); }

RegistrationResult register_clouds(const std::vector<Eigen::Vector3f>& source,
                                   const std::vector<Eigen::Vector3f>& target, const Eigen::Isometry3d& initial,
                                   const RegistrationParams& p) {
  return register_clouds(PreparedCloud(source, p), PreparedCloud(target, p), initial, p);
}

RegistrationResult register_clouds(const PreparedCloud& source, const PreparedCloud& target,
                                   const Eigen::Isometry3d& initial, const RegistrationParams& p) {
  RegistrationResult r;
  const std::vector<Eigen::Vector3d>& src = source.gicp().points();
  if (src.size() < 20 || target.size() < 20) {
    return r;
  }
  odometry::PairRegistrationParams pp;
  pp.method = odometry::PairMethod::kGicp;
  pp.gicp_max_correspondence_m = p.max_correspondence_m;
  pp.gicp_max_iterations = p.max_iterations;
  const odometry::RegistrationOutput g = odometry::register_gicp(source.gicp(), target.gicp(), initial, pp);
  // Usable when it ran to the end with enough correspondences, converged or at the iteration limit;
  // fitness and overlap decide whether it is a loop.
  r.converged = g.correspondences >= 20;
  r.T_target_source = g.T_map_sensor;
  // Fitness and overlap over inliers.
  double sum = 0;
  size_t inliers = 0;
  for (const double d : target.gicp().nearest_distances(src, r.T_target_source)) {
    if (d <= p.inlier_distance_m) {
      sum += d * d;
      ++inliers;
    }
  }
  r.overlap = static_cast<double>(inliers) / static_cast<double>(src.size());
  r.fitness = inliers > 0 ? sum / static_cast<double>(inliers) : 1e9;
  // Information from the Hessian (right perturbation of T_target_source, both halves in the source's
  // frame): the graph's residual takes the translation in the target's frame, so rotate that block.
  Eigen::Matrix<double, 6, 6> J = Eigen::Matrix<double, 6, 6>::Identity();
  J.topLeftCorner<3, 3>() = r.T_target_source.rotation();
  const Eigen::Matrix<double, 6, 6> H = 0.5 * (g.hessian + g.hessian.transpose());
  const Eigen::Matrix<double, 6, 6> info = p.information_scale * (J * H * J.transpose());
  if (info.allFinite() && Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, 6, 6>>(info).eigenvalues()(0) > 0) {
    r.information = 0.5 * (info + info.transpose());
  } else {
    r.converged = false;  // a Hessian that is not positive definite leaves a direction unconstrained
  }
  return r;
}

}  // namespace cdc::lidar
