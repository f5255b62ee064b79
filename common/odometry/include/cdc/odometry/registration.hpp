// Scan-to-map registration: Gauss-Newton over SE(3) of point-to-plane residuals, the plane through
// the voxel map's nearest point with the scan point's own surface normal (estimated on the scan's
// range image, where a spinning LiDAR's neighbouring rings give well-defined ground and wall
// normals; point-to-point residuals on ground rings, which move with the sensor, would pull the
// estimate towards zero motion). Geman-McClure kernel and a correspondence gate, both set by the
// caller from its motion-prediction error as KISS-ICP does.
#pragma once

#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

namespace cdc::odometry {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct RegistrationParams {
  int max_iterations = 50;
  double convergence = 5e-4;          // stop when the update is below this (m and rad)
  double max_correspondence_m = 1.5;  // gate on the distance to the nearest map point
  double kernel_m = 0.5;              // Geman-McClure scale [m]
};

struct RegistrationOutput {
  Eigen::Isometry3d T_map_sensor = Eigen::Isometry3d::Identity();
  Matrix6d hessian = Matrix6d::Zero();  // (t, r) order, right perturbation, last iteration, [1/m^2]
  int correspondences = 0;
  int iterations = 0;
  double rmse = 0;  // of the correspondences [m]
  bool converged = false;
};

// normals_sensor: unit normals of the points (sensor frame), same length.
RegistrationOutput register_to_map(const std::vector<Eigen::Vector3d>& points_sensor,
                                   const std::vector<Eigen::Vector3d>& normals_sensor, const VoxelMap& map,
                                   const Eigen::Isometry3d& guess, const RegistrationParams& params);

// How well a registered sweep fits the map, for telling a registration that found the sweep's place
// from one that settled in a wrong minimum: of the points with a normal, those whose nearest map
// point lies within max_distance_m and whose distance to the plane through it (the point's own
// normal) is below inlier_m.
struct FitQuality {
  int points = 0;  // points with a normal
  int inliers = 0;
  double inlier_fraction = 0;  // inliers / points
  double inlier_rms = 0;       // plane distance of the inliers [m]
};
FitQuality evaluate_fit(const std::vector<Eigen::Vector3d>& points_sensor,
                        const std::vector<Eigen::Vector3d>& normals_sensor, const VoxelMap& map,
                        const Eigen::Isometry3d& T_map_sensor, double max_distance_m, double inlier_m);

// Normals of a sweep on its range image: `ring` per point (0 = lowest beam), azimuth from x, y.
// Each normal is the cross product of the neighbours along the ring and across the rings; points
// whose neighbours are missing, too far or not coplanar get a zero normal.
std::vector<Eigen::Vector3d> range_image_normals(const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<uint16_t>& rings, int columns = 1800,
                                                 double max_neighbour_m = 3.0);

// Normals for clouds without ring structure (a saved scan, a map): the smallest principal
// direction of each query point's k nearest neighbours in `cloud` (nanoflann k-d tree); zero
// when the neighbourhood is not planar or spans more than max_neighbour_m.
std::vector<Eigen::Vector3d> knn_normals(const std::vector<Eigen::Vector3d>& queries,
                                         const std::vector<Eigen::Vector3d>& cloud, int k = 10,
                                         double max_neighbour_m = 2.0);

}  // namespace cdc::odometry
