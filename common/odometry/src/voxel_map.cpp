#include "cdc/odometry/voxel_map.hpp"

#include <cmath>
#include <limits>

namespace cdc::odometry {

VoxelMap::Key VoxelMap::key_of(const Eigen::Vector3d& p) const {
  return {static_cast<int32_t>(std::floor(p.x() / p_.voxel_m)), static_cast<int32_t>(std::floor(p.y() / p_.voxel_m)),
          static_cast<int32_t>(std::floor(p.z() / p_.voxel_m))};
}

void VoxelMap::add(const std::vector<Eigen::Vector3d>& pts) {
  const size_t cap = static_cast<size_t>(p_.max_points);
  for (const auto& p : pts) {
    auto& v = voxels_[key_of(p)];
    if (v.size() < cap) {
      if (v.empty()) v.reserve(cap);
      v.push_back(p);
    }
  }
}

void VoxelMap::remove_far(const Eigen::Vector3d& c) {
  const double lim2 = p_.max_range_m * p_.max_range_m;
  for (auto it = voxels_.begin(); it != voxels_.end();) {
    it = (it->second.front() - c).squaredNorm() > lim2 ? voxels_.erase(it) : std::next(it);
  }
}

size_t VoxelMap::points() const noexcept {
  size_t n = 0;
  for (const auto& [k, v] : voxels_) n += v.size();
  return n;
}

bool VoxelMap::nearest(const Eigen::Vector3d& q, Eigen::Vector3d& out, double& best, double max_distance2) const {
  const Key k = key_of(q);
  const double v = p_.voxel_m;
  // Distance from q to its voxel's lower and upper faces along each axis.
  const Eigen::Vector3d lo(q.x() - k.x * v, q.y() - k.y * v, q.z() - k.z * v);
  const Eigen::Vector3d hi = Eigen::Vector3d::Constant(v) - lo;
  best = max_distance2;
  bool found = false;
  auto visit = [&](int dx, int dy, int dz) {
    // Skip a neighbour whose box is farther than the best point so far.
    double box = 0;
    if (dx != 0) box += dx < 0 ? lo.x() * lo.x() : hi.x() * hi.x();
    if (dy != 0) box += dy < 0 ? lo.y() * lo.y() : hi.y() * hi.y();
    if (dz != 0) box += dz < 0 ? lo.z() * lo.z() : hi.z() * hi.z();
    if (box >= best) return;
    const auto it = voxels_.find(Key{k.x + dx, k.y + dy, k.z + dz});
    if (it == voxels_.end()) return;
    for (const auto& p : it->second) {
      const double d2 = (p - q).squaredNorm();
      if (d2 < best) {
        best = d2;
        out = p;
        found = true;
      }
    }
  };
  visit(0, 0, 0);
  for (int dx = -1; dx <= 1; ++dx) {
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dz = -1; dz <= 1; ++dz) {
        if (dx != 0 || dy != 0 || dz != 0) visit(dx, dy, dz);
      }
    }
  }
  return found;
}

namespace {

// The integer voxel of a point, and its hash, for the filters below.
Eigen::Vector3i voxel_of(const Eigen::Vector3d& p, double voxel_m) {
  return {static_cast<int>(std::floor(p.x() / voxel_m)), static_cast<int>(std::floor(p.y() / voxel_m)),
          static_cast<int>(std::floor(p.z() / voxel_m))};
}

struct VoxelOfHash {
  size_t operator()(const Eigen::Vector3i& k) const noexcept { return voxel_hash(k.x(), k.y(), k.z()); }
};

}  // namespace

std::vector<size_t> voxel_filter_indices(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  std::unordered_map<Eigen::Vector3i, bool, VoxelOfHash> seen;
  seen.reserve(points.size());
  std::vector<size_t> out;
  out.reserve(points.size() / 2);
  for (size_t i = 0; i < points.size(); ++i) {
    if (seen.emplace(voxel_of(points[i], voxel_m), true).second) out.push_back(i);
  }
  return out;
}

std::vector<Eigen::Vector3d> voxel_centroids(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  std::unordered_map<Eigen::Vector3i, size_t, VoxelOfHash> slot;  // voxel -> index into the sums
  slot.reserve(points.size());
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  for (const Eigen::Vector3d& p : points) {
    const auto [it, added] = slot.emplace(voxel_of(p, voxel_m), sum.size());
    if (added) {
      sum.push_back(p);
      count.push_back(1);
    } else {
      sum[it->second] += p;
      ++count[it->second];
    }
  }
  for (size_t i = 0; i < sum.size(); ++i) sum[i] /= static_cast<double>(count[i]);
  return sum;
}

std::vector<Eigen::Vector3d> voxel_filter(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  std::vector<Eigen::Vector3d> out;
  for (size_t i : voxel_filter_indices(points, voxel_m)) out.push_back(points[i]);
  return out;
}

}  // namespace cdc::odometry
