// Global registration of two sweeps without an initial guess: FPFH features (Rusu et al., ICRA
// 2009) on voxel-reduced clouds, mutual nearest neighbours in feature space as matches, and RANSAC
// over three matches at a time with an edge-length pre-test (the sample-consensus scheme of PCL's
// and Open3D's feature registration). The front-end uses it to recover a scan-to-map registration
// that its motion prediction led astray (a sharp turn between two sweeps of a hand-held LiDAR).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <vector>

namespace cdc::odometry {

struct GlobalRegistrationParams {
  double voxel_m = 0.5;           // both clouds reduced to voxel centroids
  double normal_radius_m = 1.0;   // normals from the neighbours within (at least 5)
  double feature_radius_m = 2.5;  // FPFH support
  double inlier_m = 0.75;         // a match this close after the transform is an inlier
  int iterations = 10000;         // RANSAC samples
  double edge_ratio = 0.9;        // a sample's three edges must agree in length within this ratio
  uint32_t seed = 1;              // samples come from a generator seeded with this: deterministic
};

// A cloud made ready for global registration: its voxel centroids, their normals (towards the
// sensor, at the cloud's origin) and FPFH features; points without a normal carry none.
struct FeatureCloud {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector3d> normals;               // zero: no normal (and no feature)
  std::vector<Eigen::Matrix<float, 33, 1>> features;  // FPFH, each of its 3 histograms sums to 100
  std::vector<size_t> with_feature;                   // indices of the points that carry one
};

FeatureCloud make_feature_cloud(const std::vector<Eigen::Vector3d>& points_sensor,
                                const GlobalRegistrationParams& params);

struct GlobalRegistrationResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  int matches = 0;  // mutual feature matches
  int inliers = 0;  // matches within inlier_m under T_target_source (refitted to all of them)
  bool ok = false;  // a consensus of at least 3 matches was found
};

GlobalRegistrationResult register_global(const FeatureCloud& source, const FeatureCloud& target,
                                         const GlobalRegistrationParams& params);

}  // namespace cdc::odometry
