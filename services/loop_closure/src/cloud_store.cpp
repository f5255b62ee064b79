#include "cdc/loop_closure/cloud_store.hpp"

#include "cdc/lidar/ground.hpp"

#include <algorithm>

namespace cdc::loops {

CloudStore::CloudStore(const LoopParams& params)
    : voxel_m_(params.registration.voxel_m),
      cache_size_(params.cloud_cache),
      prepared_size_(params.prepared_clouds),
      registration_(params.registration) {
  registration_.voxel_m = 0;  // the held clouds are downsampled already
}

void CloudStore::add_local(const KeyframeId& id, const std::vector<Eigen::Vector3f>& cloud, const Eigen::Vector3d& up) {
  up_[id] = up;
  set_cloud(id, cloud);
  local_.insert(id);
}

void CloudStore::add_received(const KeyframeId& id, const std::vector<Eigen::Vector3f>& cloud) {
  if (is_local(id)) return;
  set_cloud(id, cloud);
  received_.erase(std::remove(received_.begin(), received_.end(), id), received_.end());  // received again
  received_.push_back(id);
  while (received_.size() > cache_size_) {
    clouds_.erase(received_.front());
    ground_.erase(received_.front());
    drop_prepared(received_.front());
    received_.pop_front();
  }
}

const std::vector<Eigen::Vector3f>* CloudStore::find(const KeyframeId& id) const {
  auto it = clouds_.find(id);
  return it == clouds_.end() ? nullptr : &it->second;
}

Eigen::Vector3d CloudStore::up(const KeyframeId& id) const {
  const auto it = up_.find(id);
  return it == up_.end() ? Eigen::Vector3d::UnitZ() : it->second;
}

std::optional<double> CloudStore::ground(const KeyframeId& id) const {
  const auto it = ground_.find(id);
  return it == ground_.end() ? std::nullopt : it->second;
}

void CloudStore::set_cloud(const KeyframeId& id, const std::vector<Eigen::Vector3f>& cloud) {
  clouds_[id] = odometry::voxel_centroids(cloud, voxel_m_);
  ground_[id] = lidar::ground_height(clouds_[id], up(id));
  drop_prepared(id);
}

void CloudStore::drop_prepared(const KeyframeId& id) {
  prepared_.erase(std::remove_if(prepared_.begin(), prepared_.end(), [&](const auto& e) { return e.first == id; }),
                  prepared_.end());
}

std::shared_ptr<const odometry::PreparedCloud> CloudStore::prepared(const KeyframeId& id) {
  const auto held = clouds_.find(id);
  if (held == clouds_.end()) return nullptr;
  const auto it = std::find_if(prepared_.begin(), prepared_.end(), [&](const auto& e) { return e.first == id; });
  if (it != prepared_.end()) {
    ++stats_.prepared_reused;
    auto entry = *it;
    prepared_.erase(it);
    prepared_.push_front(entry);
    return entry.second;
  }
  auto ready = std::make_shared<const odometry::PreparedCloud>(held->second, registration_);
  ++stats_.prepared;
  if (prepared_size_ > 0) {
    prepared_.emplace_front(id, ready);
    while (prepared_.size() > prepared_size_) prepared_.pop_back();
  }
  return ready;
}

}  // namespace cdc::loops
