// The keyframe clouds held by the loop-closure core, downsampled to the registration's voxel size:
// this robot's own (local) ones with the direction of up in each, kept for good, and peers' clouds
// received on request, the cloud_cache most recent of them. The few clouds used most recently are
// also kept ready for registration (k-d tree and GICP covariances, prepared_clouds of them): the
// verifications of one query, or against one requested cloud, come in bursts.
#pragma once

#include "cdc/loop_closure/loop_types.hpp"
#include "cdc/odometry/registration.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <utility>
#include <vector>

namespace cdc::loops {

struct CloudStoreStats {
  // Clouds made ready for registration; look-ups (two per registration) that found one ready.
  uint64_t prepared = 0, prepared_reused = 0;
};

class CloudStore {
 public:
  explicit CloudStore(const LoopParams& params);

  // A keyframe of this robot: its cloud (keyframe frame) and where up is in that frame.
  void add_local(const KeyframeId& id, const std::vector<Eigen::Vector3f>& cloud, const Eigen::Vector3d& up);
  // A peer's cloud received (ignored for a local keyframe); the oldest received beyond cloud_cache
  // are dropped.
  void add_received(const KeyframeId& id, const std::vector<Eigen::Vector3f>& cloud);

  bool holds(const KeyframeId& id) const { return clouds_.count(id) != 0; }
  bool is_local(const KeyframeId& id) const { return local_.count(id) != 0; }
  // The downsampled cloud, or null.
  const std::vector<Eigen::Vector3f>* find(const KeyframeId& id) const;
  // Up in a local keyframe's frame; +z for others.
  Eigen::Vector3d up(const KeyframeId& id) const;
  // The ground's height along up() in a held cloud's frame (lidar::ground_height), or nullopt.
  std::optional<double> ground(const KeyframeId& id) const;
  // A held cloud ready for registration (made ready now unless it is among the prepared_clouds kept).
  std::shared_ptr<const odometry::PreparedCloud> prepared(const KeyframeId& id);

  const CloudStoreStats& stats() const noexcept { return stats_; }

 private:
  void set_cloud(const KeyframeId& id, const std::vector<Eigen::Vector3f>& cloud);  // also drops a prepared one
  void drop_prepared(const KeyframeId& id);

  double voxel_m_;
  size_t cache_size_, prepared_size_;
  odometry::RegistrationSettings registration_;  // for preparing the (already downsampled) clouds
  std::map<KeyframeId, std::vector<Eigen::Vector3f>> clouds_;
  std::set<KeyframeId> local_;
  std::map<KeyframeId, Eigen::Vector3d> up_;
  std::map<KeyframeId, std::optional<double>> ground_;
  std::deque<KeyframeId> received_;  // peers' clouds held, oldest first
  // Clouds ready for registration, most recently used first.
  std::deque<std::pair<KeyframeId, std::shared_ptr<const odometry::PreparedCloud>>> prepared_;
  CloudStoreStats stats_;
};

}  // namespace cdc::loops
