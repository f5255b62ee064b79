// Pairwise registration of two clouds (generalized ICP, the odometry library's), for loop-closure
// verification; callers pass plain Eigen points.
#pragma once

#include <Eigen/Geometry>

#include <memory>
#include <vector>

namespace cdc::odometry {
class GicpCloud;
}

namespace cdc::lidar {

struct RegistrationParams {
  double max_correspondence_m = 2.0;  // GICP correspondence distance
  // A true loop converges in 2-9 iterations from the verification's guess; a false candidate mostly runs
  // to the limit and then fails on overlap. At 15 (was 40), cdc-loops run on the simulated KITTI 05 (900
  // scans) and 06 splits keeps the same 330 / 313 loops with the same errors, in 22 % / 12 % less time.
  int max_iterations = 15;
  int neighbours = 20;  // points per GICP covariance (10 leaves a sparse sweep's ground line-like: tilt errors)
  double inlier_distance_m = 0.5;  // for fitness and overlap after convergence
  double voxel_m = 0.4;            // downsampling of both clouds before registration (0: none)
  // GICP Hessian at the solution -> information. 0.03 puts sigma at about 1.4x the error measured on the
  // simulated KITTI-05 loops (cdc-loops run: 8 / 3 / 6 mm, 0.05 / 0.07 / 0.007 deg RMS, x y z, roll pitch yaw).
  double information_scale = 0.03;
};

struct RegistrationResult {
  bool converged = false;  // it ran to the end (converged or at max_iterations) with 20 or more correspondences
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  double fitness = 1e9;  // mean squared distance of inliers [m^2]
  double overlap = 0;    // fraction of source points with a target point within inlier_distance
  // information_scale x the GICP Hessian, in the pose graph's between-factor residual: translation in
  // the target's frame, rotation in the source's, (t, r) order. Identity when it did not converge.
  Eigen::Matrix<double, 6, 6> information = Eigen::Matrix<double, 6, 6>::Identity();
};

RegistrationResult register_clouds(const std::vector<Eigen::Vector3f>& source,
                                   const std::vector<Eigen::Vector3f>& target,
                                   const Eigen::Isometry3d& initial_T_target_source, const RegistrationParams& params);

// A cloud reduced (params.voxel_m) and made ready for registration once (its k-d tree and GICP
// covariances from params.neighbours points, ~1 MB for 8000 points), for a cloud that takes part in
// several registrations. Immutable; share it by pointer.
class PreparedCloud {
 public:
  PreparedCloud(const std::vector<Eigen::Vector3f>& points, const RegistrationParams& params);
  size_t size() const;
  const odometry::GicpCloud& gicp() const { return *gicp_; }

 private:
  std::shared_ptr<const odometry::GicpCloud> gicp_;
};

// The same registration between prepared clouds (the same result as the overload above on the same
// points and parameters); voxel_m and neighbours are the preparation's, the rest come from params.
RegistrationResult register_clouds(const PreparedCloud& source, const PreparedCloud& target,
                                   const Eigen::Isometry3d& initial_T_target_source, const RegistrationParams& params);

// Voxel-grid downsampling (one point, the centroid, per occupied voxel).
std::vector<Eigen::Vector3f> voxel_downsample(const std::vector<Eigen::Vector3f>& points, double voxel_m);

}  // namespace cdc::lidar
