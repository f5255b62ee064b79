// A flat hash table from integer voxel coordinates to a 32-bit payload (open addressing, linear
// probing, power-of-two capacity at most half full), for the voxel map and the voxel filters: one
// contiguous array and no allocation per voxel, where std::unordered_map chases a node per entry.
// No erase: the map rebuilds the index when it drops voxels.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace cdc::odometry {

// The integer voxel holding p (floor of p / voxel_m per axis), clamped to +-2^30 so that no
// coordinate, however far or non-finite, overflows the cast (NaN lands at -2^30).
inline Eigen::Vector3i voxel_coordinates(const Eigen::Vector3d& p, double voxel_m) noexcept {
  constexpr double kLimit = 1073741824.0;  // 2^30
  auto axis = [&](double v) {
    double q = v / voxel_m;
    q = q > -kLimit ? (q < kLimit ? q : kLimit) : -kLimit;
    const auto i = static_cast<int32_t>(q);  // towards zero; floor is one less below a negative non-integer
    return static_cast<double>(i) > q ? i - 1 : i;
  };
  return {axis(p.x()), axis(p.y()), axis(p.z())};
}

class VoxelIndex {
 public:
  static constexpr uint32_t kNone = 0xFFFFFFFFu;  // "absent"; never stored as a payload

  explicit VoxelIndex(size_t expected = 0) { reserve(expected); }

  // Room for n voxels without growing.
  void reserve(size_t n) {
    size_t cap = 16;
    while (cap < 2 * n) cap *= 2;
    if (cap > slots_.size()) rehash(cap);
  }
  void clear() {
    std::fill(slots_.begin(), slots_.end(), Slot{});
    size_ = 0;
  }
  size_t size() const noexcept { return size_; }

  // The payload stored for k, or kNone.
  uint32_t find(const Eigen::Vector3i& k) const noexcept {
    for (size_t i = hash(k) & mask_;; i = (i + 1) & mask_) {
      const Slot& s = slots_[i];
      if (s.value == kNone) return kNone;
      if (s.x == k.x() && s.y == k.y() && s.z == k.z()) return s.value;
    }
  }
  // Stores (k, value) unless k is present; returns the payload stored for k and whether it was added.
  std::pair<uint32_t, bool> insert(const Eigen::Vector3i& k, uint32_t value) {
    if (2 * (size_ + 1) > slots_.size()) rehash(2 * slots_.size());
    for (size_t i = hash(k) & mask_;; i = (i + 1) & mask_) {
      Slot& s = slots_[i];
      if (s.value == kNone) {
        s = Slot{k.x(), k.y(), k.z(), value};
        ++size_;
        return {value, true};
      }
      if (s.x == k.x() && s.y == k.y() && s.z == k.z()) return {s.value, false};
    }
  }

 private:
  struct Slot {
    int32_t x = 0, y = 0, z = 0;
    uint32_t value = kNone;
  };
  // Multiplicative mixing of the three coordinates, folded so that the low bits (the table's) depend
  // on all of them.
  static size_t hash(const Eigen::Vector3i& k) noexcept {
    uint64_t h = static_cast<uint64_t>(static_cast<uint32_t>(k.x())) * 0x9E3779B97F4A7C15ull;
    h ^= static_cast<uint64_t>(static_cast<uint32_t>(k.y())) * 0xC2B2AE3D27D4EB4Full;
    h ^= static_cast<uint64_t>(static_cast<uint32_t>(k.z())) * 0x165667B19E3779F9ull;
    return static_cast<size_t>(h ^ (h >> 32));
  }
  void rehash(size_t capacity) {
    std::vector<Slot> old = std::move(slots_);
    slots_.assign(capacity, Slot{});
    mask_ = capacity - 1;
    size_ = 0;
    for (const Slot& s : old) {
      if (s.value != kNone) insert(Eigen::Vector3i(s.x, s.y, s.z), s.value);
    }
  }

  std::vector<Slot> slots_;
  size_t mask_ = 0, size_ = 0;
};

}  // namespace cdc::odometry
