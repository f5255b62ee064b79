// A local map for scan-to-map registration (in the spirit of KISS-ICP): a hash of voxels, each
// holding at most `max_points` map points, so the map's memory is bounded by the volume around
// the robot; voxels farther than max_range_m from the robot are dropped as it moves. Nearest
// neighbours are searched in a query's voxel and its 26 neighbours.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

namespace cdc::odometry {

// The spatial hash of an integer voxel coordinate (Teschner et al.), shared by the map and the filter.
inline size_t voxel_hash(int32_t x, int32_t y, int32_t z) noexcept {
  return (static_cast<size_t>(static_cast<uint32_t>(x)) * 73856093u) ^ (static_cast<size_t>(static_cast<uint32_t>(y)) * 19349663u) ^
         (static_cast<size_t>(static_cast<uint32_t>(z)) * 83492791u);
}

struct VoxelMapParams {
  double voxel_m = 1.0;
  double max_range_m = 100.0;   // voxels whose centre is farther from the robot are dropped
  int max_points = 20;          // points kept per voxel
};

class VoxelMap {
 public:
  explicit VoxelMap(const VoxelMapParams& params = {}) : p_(params) {}

  void add(const std::vector<Eigen::Vector3d>& world_points);
  void remove_far(const Eigen::Vector3d& robot_position);

  // The map point nearest to q among q's voxel and its 26 neighbours, if one lies within
  // sqrt(max_distance2) (neighbour voxels farther than the best so far are not visited).
  bool nearest(const Eigen::Vector3d& q, Eigen::Vector3d& out, double& distance2,
               double max_distance2 = std::numeric_limits<double>::infinity()) const;

  size_t voxels() const noexcept { return voxels_.size(); }
  size_t points() const noexcept;
  bool empty() const noexcept { return voxels_.empty(); }
  const VoxelMapParams& params() const noexcept { return p_; }

 private:
  struct Key {
    int32_t x, y, z;
    bool operator==(const Key& o) const noexcept { return x == o.x && y == o.y && z == o.z; }
  };
  struct KeyHash {
    size_t operator()(const Key& k) const noexcept { return voxel_hash(k.x, k.y, k.z); }
  };
  Key key_of(const Eigen::Vector3d& p) const;

  VoxelMapParams p_;
  std::unordered_map<Key, std::vector<Eigen::Vector3d>, KeyHash> voxels_;
};

// Keeps the first point that falls into each voxel (order-preserving, no averaging).
std::vector<Eigen::Vector3d> voxel_filter(const std::vector<Eigen::Vector3d>& points, double voxel_m);
// The same selection, as indices into `points`.
std::vector<size_t> voxel_filter_indices(const std::vector<Eigen::Vector3d>& points, double voxel_m);
// The centroid of each occupied voxel (smoother than keeping one point: the quantisation averages out).
std::vector<Eigen::Vector3d> voxel_centroids(const std::vector<Eigen::Vector3d>& points, double voxel_m);

}  // namespace cdc::odometry
