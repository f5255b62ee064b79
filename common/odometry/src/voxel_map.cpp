#include "cdc/odometry/voxel_map.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>

namespace cdc::odometry {

VoxelMap::VoxelMap(const VoxelMapParams& params)
    : p_(params), cap_(static_cast<size_t>(std::max(1, params.max_points))) {}

void VoxelMap::add(const std::vector<Eigen::Vector3d>& pts) {
  for (const auto& p : pts) {
    const Key k = key_of(p);
    uint32_t slot = index_.find(k);
    if (slot == VoxelIndex::kNone) {
      if (!free_.empty()) {
        slot = free_.back();
        free_.pop_back();
        keys_[slot] = k;
      } else {
        slot = static_cast<uint32_t>(keys_.size());
        keys_.push_back(k);
        counts_.push_back(0);
        points_.resize(points_.size() + cap_);
      }
      index_.insert(k, slot);
    }
    uint32_t& n = counts_[slot];
    if (n < cap_) points_[slot * cap_ + n++] = p;
  }
}

void VoxelMap::remove_far(const Eigen::Vector3d& c) {
  const double lim2 = p_.max_range_m * p_.max_range_m;
  bool removed = false;
  for (uint32_t slot = 0; slot < counts_.size(); ++slot) {
    // A voxel's first point stands for it (its position within a voxel's width).
    if (counts_[slot] == 0 || (points_[slot * cap_] - c).squaredNorm() <= lim2) continue;
    counts_[slot] = 0;
    free_.push_back(slot);
    removed = true;
  }
  if (removed) reindex();
}

void VoxelMap::reindex() {
  index_ = VoxelIndex(counts_.size() - free_.size());
  for (uint32_t slot = 0; slot < counts_.size(); ++slot) {
    if (counts_[slot] > 0) index_.insert(keys_[slot], slot);
  }
  // Reuse the lowest slots first (the free list is a stack).
  std::sort(free_.begin(), free_.end(), std::greater<>());
}

size_t VoxelMap::points() const noexcept {
  size_t n = 0;
  for (uint32_t c : counts_) n += c;
  return n;
}

bool VoxelMap::nearest(const Eigen::Vector3d& q, Eigen::Vector3d& out, double& best, double max_distance2) const {
  const Key k = key_of(q);
  const double v = p_.voxel_m;
  // Distance from q to its voxel's lower and upper faces along each axis.
  const Eigen::Vector3d lo(q.x() - k.x() * v, q.y() - k.y() * v, q.z() - k.z() * v);
  const Eigen::Vector3d hi = Eigen::Vector3d::Constant(v) - lo;
  best = max_distance2;
  const Eigen::Vector3d* found = nullptr;
  auto visit = [&](int dx, int dy, int dz) {
    // Skip a neighbour whose box is farther than the best point so far.
    double box = 0;
    if (dx != 0) box += dx < 0 ? lo.x() * lo.x() : hi.x() * hi.x();
    if (dy != 0) box += dy < 0 ? lo.y() * lo.y() : hi.y() * hi.y();
    if (dz != 0) box += dz < 0 ? lo.z() * lo.z() : hi.z() * hi.z();
    if (box >= best) return;
    const uint32_t slot = index_.find(Key(k.x() + dx, k.y() + dy, k.z() + dz));
    if (slot == VoxelIndex::kNone) return;
    const Eigen::Vector3d* p = points_.data() + slot * cap_;
    for (const Eigen::Vector3d* e = p + counts_[slot]; p != e; ++p) {
      const double d2 = (*p - q).squaredNorm();
      if (d2 < best) {
        best = d2;
        found = p;
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
  if (found == nullptr) return false;
  out = *found;
  return true;
}

std::vector<size_t> voxel_filter_indices(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  VoxelIndex seen(points.size() / 2);
  std::vector<size_t> out;
  out.reserve(points.size() / 2);
  // A sweep in firing order puts consecutive points mostly in the same voxel: the previous point's
  // voxel, already seen, is checked before the table.
  Eigen::Vector3i last(0, 0, 0);
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3i k = voxel_coordinates(points[i], voxel_m);
    if (i > 0 && k == last) continue;
    last = k;
    if (seen.insert(k, 0).second) out.push_back(i);
  }
  return out;
}

std::vector<Eigen::Vector3d> voxel_centroids(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  VoxelIndex slot(points.size() / 4);  // voxel -> index into the sums
  std::vector<Eigen::Vector3d> sum;
  std::vector<int> count;
  for (const Eigen::Vector3d& p : points) {
    const auto [i, added] = slot.insert(voxel_coordinates(p, voxel_m), static_cast<uint32_t>(sum.size()));
    if (added) {
      sum.push_back(p);
      count.push_back(1);
    } else {
      sum[i] += p;
      ++count[i];
    }
  }
  for (size_t i = 0; i < sum.size(); ++i) sum[i] /= static_cast<double>(count[i]);
  return sum;
}

std::vector<Eigen::Vector3f> voxel_centroids(const std::vector<Eigen::Vector3f>& points, double voxel_m) {
  if (voxel_m <= 0) return points;
  std::vector<Eigen::Vector3d> d;
  d.reserve(points.size());
  for (const Eigen::Vector3f& p : points) d.push_back(p.cast<double>());
  std::vector<Eigen::Vector3f> out;
  for (const Eigen::Vector3d& c : voxel_centroids(d, voxel_m)) out.push_back(c.cast<float>());
  return out;
}

std::vector<Eigen::Vector3d> voxel_filter(const std::vector<Eigen::Vector3d>& points, double voxel_m) {
  const std::vector<size_t> keep = voxel_filter_indices(points, voxel_m);
  std::vector<Eigen::Vector3d> out;
  out.reserve(keep.size());
  for (size_t i : keep) out.push_back(points[i]);
  return out;
}

}  // namespace cdc::odometry
