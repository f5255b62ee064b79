// Pairwise registration of two clouds (generalized ICP, the odometry library's), for loop-closure
// verification; callers pass plain Eigen points.
#pragma once

#include <Eigen/Geometry>

#include <vector>

namespace cdc::lidar {

struct RegistrationParams {
  double max_correspondence_m = 2.0;  // GICP correspondence distance
  int max_iterations = 40;
  int neighbours = 10;                // points per GICP covariance
  double inlier_distance_m = 0.5;     // for fitness and overlap after convergence
  double voxel_m = 0.4;               // downsampling of both clouds before registration (0: none)
};

struct RegistrationResult {
  bool converged = false;  // it ran to the end (converged or at max_iterations) with 20 or more correspondences
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  double fitness = 1e9;   // mean squared distance of inliers [m^2]
  double overlap = 0;     // fraction of source points with a target point within inlier_distance
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();  // (t, r) order
};

RegistrationResult register_clouds(const std::vector<Eigen::Vector3f>& source, const std::vector<Eigen::Vector3f>& target,
                                   const Eigen::Isometry3d& initial_T_target_source, const RegistrationParams& params);

// Voxel-grid downsampling (one point, the centroid, per occupied voxel).
std::vector<Eigen::Vector3f> voxel_downsample(const std::vector<Eigen::Vector3f>& points, double voxel_m);

}  // namespace cdc::lidar
