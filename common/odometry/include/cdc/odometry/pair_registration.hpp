// Registration of one saved sweep onto another (no motion prediction), by one of two methods:
// point-to-plane (the target becomes a voxel map, the source's normals come from its own
// neighbourhoods, and register_to_map runs from the guess with a correspondence gate that shrinks
// coarse to fine), or generalized ICP (plane-to-plane on both clouds' local covariances). Used by
// cdc-register and by the tests on real sweep pairs.
#pragma once

#include "cdc/odometry/registration.hpp"

#include <Eigen/Geometry>

#include <memory>
#include <string>
#include <vector>

namespace cdc::odometry {

enum class PairMethod {
  kPointToPlane,  // the front-end's registration: the target as a voxel map, coarse-to-fine gates
  kGicp,          // generalized ICP: plane-to-plane, both clouds' local covariances (Segal et al. 2009)
};

struct PairRegistrationParams {
  PairMethod method = PairMethod::kPointToPlane;
  double source_voxel_m = 0.5;  // downsampling of the registered source points
  double target_voxel_m = 0.1;  // downsampling of the target points put in the map
  double map_voxel_m = 0.5;     // the map's voxel
  int normal_neighbours = 10;   // source normals: k nearest points within normal_radius_m
  double normal_radius_m = 1.5;
  std::vector<double> gates_m = {2.0, 1.0, 0.5, 0.25, 0.1};  // coarse to fine; kernel = gate / 3
  // GICP: both clouds reduced to voxel centroids (gicp_voxel_m), covariances from gicp_neighbours
  // points (flattened to planes), correspondences within gicp_max_correspondence_m. The defaults
  // suit dense sweeps (64 beams); on sparse ones (16 beams) a point's neighbours lie on its own ring,
  // and voxels coarser than the ring spacing (0.5 m) are needed.
  double gicp_voxel_m = 0.1;  // 0: the clouds as given (already reduced)
  int gicp_neighbours = 10;
  double gicp_max_correspondence_m = 1.0;
  int gicp_max_iterations = 64;
};

// T_target_source (as RegistrationOutput::T_map_sensor) of the last, finest stage.
RegistrationOutput register_pair(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                                 const Eigen::Isometry3d& guess, const PairRegistrationParams& params);

// For each source point moved by T_target_source, the distance to its nearest target point (loop
// verification's fitness and overlap start from these).
std::vector<double> nearest_distances(const std::vector<Eigen::Vector3d>& source,
                                      const std::vector<Eigen::Vector3d>& target,
                                      const Eigen::Isometry3d& T_target_source);

// A cloud made ready for GICP once: its points as given (no reduction), their k-d tree and plane
// covariances from `neighbours` points, so that registering it against several others (loop
// verification) computes them once. Not copyable or movable (the tree refers to the points).
class GicpCloud {
 public:
  GicpCloud(std::vector<Eigen::Vector3d> points, int neighbours);
  ~GicpCloud();
  GicpCloud(const GicpCloud&) = delete;
  GicpCloud& operator=(const GicpCloud&) = delete;

  const std::vector<Eigen::Vector3d>& points() const;
  // For each source point moved by T_this_source, the distance to its nearest point here.
  std::vector<double> nearest_distances(const std::vector<Eigen::Vector3d>& source,
                                        const Eigen::Isometry3d& T_this_source) const;

  struct Impl;  // points, tree, covariances (pair_registration.cpp)
  const Impl& impl() const { return *impl_; }

 private:
  std::unique_ptr<Impl> impl_;
};

// GICP between two prepared clouds from `guess`; uses gicp_max_correspondence_m and
// gicp_max_iterations of `params` (the clouds' preparation fixed the rest). The same result as
// register_pair with kGicp on the same points with gicp_voxel_m 0.
RegistrationOutput register_gicp(const GicpCloud& source, const GicpCloud& target, const Eigen::Isometry3d& guess,
                                 const PairRegistrationParams& params);

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

// x, y, z of a saved sweep: KITTI velodyne .bin (float32 x y z i), binary .pcd (float32 x y z
// fields; other fields skipped) or binary little-endian .ply (float32 vertex properties). Throws
// std::runtime_error naming the file and what is wrong (unknown extension, ascii or compressed
// data, no x/y/z fields, truncated data).
std::vector<Eigen::Vector3d> read_cloud_file(const std::string& path);

// A 4x4 matrix written as 16 numbers, row by row (a reference transform). Throws when it is not
// one, or its rotation part is not a rotation.
Eigen::Isometry3d read_matrix_file(const std::string& path);

}  // namespace cdc::odometry
