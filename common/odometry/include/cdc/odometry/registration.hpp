// Registration of a source cloud onto a target: T_target_source from an initial guess by
// Gauss-Newton over SE(3) (right perturbation, (t, r) order), by one of two methods behind one
// settings struct and one result type.
// - Point-to-plane: the plane through the target's nearest point with the source point's own normal
//   (estimated on the source, e.g. on a spinning LiDAR's range image, where neighbouring rings give
//   well-defined ground and wall normals; point-to-point residuals on ground rings, which move with
//   the sensor, would pull the estimate towards zero motion), a Geman-McClure kernel and a
//   correspondence gate; the target is a voxel map. The front-end's scan-to-map registration, its
//   gate and kernel set from its motion-prediction error as KISS-ICP does.
// - Generalized ICP (Segal et al. 2009): plane-to-plane on both clouds' local covariances, each
//   cloud prepared once (PreparedCloud) so that loop verification registers it against several.
// register_to_map and register_gicp run one method on inputs made ready by the caller;
// register_clouds takes two plain clouds and the method from the settings.
#pragma once

#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

namespace cdc::odometry {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

enum class RegistrationMethod {
  kPointToPlane,  // the target as a voxel map, the source with its normals
  kGicp,          // generalized ICP: plane-to-plane on both clouds' covariances
};

// Defaults: point-to-plane as the front-end runs it; gicp() for generalized ICP on dense sweeps.
struct RegistrationSettings {
  RegistrationMethod method = RegistrationMethod::kPointToPlane;  // read by register_clouds
  int max_iterations = 50;
  double max_correspondence_m = 1.5;  // gate on the distance to the nearest target point [m]
  double translation_eps_m = 5e-4;    // converged when an update moves less than this [m]
  double rotation_eps_rad = 5e-4;     // ... and turns less than this [rad]
  double kernel_m = 0.5;              // point-to-plane: Geman-McClure scale [m]

  // Plain clouds made ready (register_clouds, PreparedCloud). Point-to-plane: the source reduced to
  // one point per voxel_m with normals from its `neighbours` nearest points within normal_radius_m,
  // the target to one point per target_voxel_m in a map of map_voxel_m voxels, and the gate
  // shrinking through gates_m (each with kernel gate / 3) in place of max_correspondence_m and
  // kernel_m. GICP: both clouds reduced to voxel_m centroids (0: as given), covariances from
  // `neighbours` points.
  double voxel_m = 0.5;
  double target_voxel_m = 0.1;
  double map_voxel_m = 0.5;
  int neighbours = 10;
  double normal_radius_m = 1.5;
  std::vector<double> gates_m = {2.0, 1.0, 0.5, 0.25, 0.1};

  // Judging the result (0: not done). inlier_distance_m: fitness and overlap over the source points
  // with a target point within it. information_scale: the result's information is this x the
  // Hessian, and a registration whose information is not positive definite has not converged.
  double inlier_distance_m = 0;
  double information_scale = 0;

  // Generalized ICP with small_gicp's settings for dense sweeps (0.1 m voxels, 10 neighbours; on
  // sparse 16-beam sweeps a point's neighbours lie on its own ring, and voxels coarser than the ring
  // spacing, 0.5 m, are needed).
  static RegistrationSettings gicp();
};

struct RegistrationResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();  // the initial guess if it never ran
  // It ran to the end (an update within the eps, or max_iterations: a warning says so) with 20 or
  // more correspondences and a finite update; with information_scale set, also a positive definite
  // information.
  bool converged = false;
  int iterations = 0;
  int correspondences = 0;              // of the last iteration
  double rmse = 0;                      // of those: distance to the plane (point-to-plane) or the point (GICP) [m]
  Matrix6d hessian = Matrix6d::Zero();  // of the last iteration, (t, r) order, right perturbation [1/m^2]
  // information_scale x the Hessian, in the pose graph's between-factor residual: translation in the
  // target's frame, rotation in the source's, (t, r) order. Identity when not positive definite.
  Matrix6d information = Matrix6d::Identity();
  double fitness = 1e9;               // mean squared distance of the inliers [m^2] (1e9: none, or not judged)
  double overlap = 0;                 // share of the source points that are inliers
  std::vector<std::string> warnings;  // why it did not converge, or that it stopped at max_iterations
};

// Point-to-plane. normals_source: unit normals of the source points (source frame; zero: none,
// the point is skipped), same length. settings.method is not read.
RegistrationResult register_to_map(const std::vector<Eigen::Vector3d>& points_source,
                                   const std::vector<Eigen::Vector3d>& normals_source, const VoxelMap& target,
                                   const Eigen::Isometry3d& initial_T_target_source,
                                   const RegistrationSettings& settings);

// A cloud made ready for GICP once: reduced to settings.voxel_m centroids (0: as given), its k-d
// tree and plane covariances from settings.neighbours points (~1 MB for 8000 points). Immutable
// and move-only; share it by pointer.
class PreparedCloud {
 public:
  PreparedCloud(const std::vector<Eigen::Vector3d>& points, const RegistrationSettings& settings);
  PreparedCloud(const std::vector<Eigen::Vector3f>& points, const RegistrationSettings& settings);
  ~PreparedCloud();
  PreparedCloud(PreparedCloud&&) noexcept;
  PreparedCloud& operator=(PreparedCloud&&) noexcept;

  const std::vector<Eigen::Vector3d>& points() const;
  size_t size() const { return points().size(); }

  struct Impl;  // points, tree, covariances (gicp.cpp)

 private:
  friend RegistrationResult register_gicp(const PreparedCloud&, const PreparedCloud&, const Eigen::Isometry3d&,
                                          const RegistrationSettings&);
  std::unique_ptr<Impl> impl_;
};

// GICP between two prepared clouds (their preparation fixed voxel_m and neighbours); the same
// result as register_clouds with kGicp on the same points and settings. Either cloud with fewer
// than 20 points: not run.
RegistrationResult register_gicp(const PreparedCloud& source, const PreparedCloud& target,
                                 const Eigen::Isometry3d& initial_T_target_source,
                                 const RegistrationSettings& settings);

// Two plain clouds made ready as the settings say and registered by settings.method.
RegistrationResult register_clouds(const std::vector<Eigen::Vector3d>& source,
                                   const std::vector<Eigen::Vector3d>& target,
                                   const Eigen::Isometry3d& initial_T_target_source,
                                   const RegistrationSettings& settings);

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

// How well T_target_source aligns two sweeps, independently of any registration's own cost: both
// clouds reduced to voxel_m, each source point moved by T and matched to its nearest target point
// within max_distance_m that lies on a plane (normal from its 10 neighbours); the RMS of the
// point-to-plane distances and the share matched. A better transform has more matches and a
// smaller RMS (used to judge reference transforms against each other).
struct AlignmentScore {
  size_t source_points = 0, matched = 0, within_1cm = 0, within_2cm = 0;
  double rms_point_to_plane_m = 0;
};
AlignmentScore score_alignment(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                               const Eigen::Isometry3d& T_target_source, double voxel_m = 0.1,
                               double max_distance_m = 0.2);

}  // namespace cdc::odometry
