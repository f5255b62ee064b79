// A local map for scan-to-map registration (in the spirit of KISS-ICP): a hash of voxels, each
// holding at most `max_points` map points, so the map's memory is bounded by the volume around
// the robot; voxels farther than max_range_m from the robot are dropped as it moves. Nearest
// neighbours are searched in a query's voxel and its 26 neighbours. The voxels live in one flat
// hash index (voxel_index.hpp) and their points in one array, max_points per voxel: a lookup is a
// probe or two in contiguous memory, not a bucket chain and a vector per voxel.
#pragma once

#include "cdc/odometry/voxel_index.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace cdc::odometry {

struct VoxelMapParams {
  double voxel_m = 1.0;
  double max_range_m = 100.0;  // voxels whose centre is farther from the robot are dropped
  int max_points = 20;         // points kept per voxel
};

class VoxelMap {
 public:
  explicit VoxelMap(const VoxelMapParams& params = {});

  void add(const std::vector<Eigen::Vector3d>& world_points);
  void remove_far(const Eigen::Vector3d& robot_position);

  // The map point nearest to q among q's voxel and its 26 neighbours, if one lies within
  // sqrt(max_distance2) (neighbour voxels farther than the best so far are not visited).
  bool nearest(const Eigen::Vector3d& q, Eigen::Vector3d& out, double& distance2,
               double max_distance2 = std::numeric_limits<double>::infinity()) const;

  size_t voxels() const noexcept { return index_.size(); }
  size_t points() const noexcept;
  bool empty() const noexcept { return index_.size() == 0; }
  const VoxelMapParams& params() const noexcept { return p_; }

 private:
  using Key = Eigen::Vector3i;
  Key key_of(const Eigen::Vector3d& p) const { return voxel_coordinates(p, p_.voxel_m); }
  // Rebuilds the index from the live slots (after remove_far freed some).
  void reindex();

  VoxelMapParams p_;
  size_t cap_ = 0;                       // max_points, as a size
  VoxelIndex index_;                     // voxel -> slot
  std::vector<Key> keys_;                // per slot: its voxel
  std::vector<uint32_t> counts_;         // per slot: points held (0: a free slot)
  std::vector<Eigen::Vector3d> points_;  // per slot: cap_ points, the first counts_[slot] of them held
  std::vector<uint32_t> free_;           // slots freed by remove_far, reused by add
};

// Keeps the first point that falls into each voxel (order-preserving, no averaging).
std::vector<Eigen::Vector3d> voxel_filter(const std::vector<Eigen::Vector3d>& points, double voxel_m);
// The same selection, as indices into `points`.
std::vector<size_t> voxel_filter_indices(const std::vector<Eigen::Vector3d>& points, double voxel_m);
// The centroid of each occupied voxel (smoother than keeping one point: the quantisation averages out).
std::vector<Eigen::Vector3d> voxel_centroids(const std::vector<Eigen::Vector3d>& points, double voxel_m);
// The same on single-precision points (loop closure keeps its clouds so); voxel_m 0: the points as given.
std::vector<Eigen::Vector3f> voxel_centroids(const std::vector<Eigen::Vector3f>& points, double voxel_m);

}  // namespace cdc::odometry
