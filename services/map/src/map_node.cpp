#include "map_node.hpp"

#include "cdc/dds/compact.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/runtime/stats.hpp"

#include <spdlog/spdlog.h>

#include <csignal>

namespace cdc::map {

MapNode::MapNode(const runtime::ServiceOptions& common, const MapNodeOptions& o)
    : o_(o),
      dir_(o.out_dir),
      service_(runtime::Domains::kSingle, common, runtime::swarm_limits(o.robots, {o.central_id})),
      clouds_(service_, service_.radio(), dds::topics::kKeyframeCloud,
              dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader())),
      poses_(service_, service_.radio(), dds::topics::kCentralOptimized,
             dds::qos::monitored_reader().partitions(dds::partitions::all_robots_reader())),
      core_(o.core),
      last_write_(std::chrono::steady_clock::now()) {
  std::filesystem::create_directories(dir_);
  dds::ShutdownSignal::on_user_signal([this](int signal) {
    if (signal == SIGUSR1) write_requested_ = true;
  });
  clouds_.on([this](const cdc_msg_KeyframeCloud& m) { on_cloud(m); });
  poses_.on([this](const cdc_msg_OptimizedPoses& m) { on_poses(m); });
  spdlog::info("map service up: cloud voxel {} m, OctoMap resolution {} m, writing to {}", o.core.voxel_m,
               o.core.octree_resolution_m, dir_.string());
}

MapNode::~MapNode() { dds::ShutdownSignal::on_user_signal({}); }

void MapNode::spin() {
  while (service_.wait(std::chrono::milliseconds(200))) {
    clouds_.poll(64);
    poses_.poll(16);
    const bool periodic = o_.write_period_s > 0 && std::chrono::steady_clock::now() - last_write_ >=
                                                       std::chrono::duration<double>(o_.write_period_s);
    if (write_requested_.exchange(false) || periodic) {
      write();
      last_write_ = std::chrono::steady_clock::now();
    }
  }
}

// The boundary has unpacked the cloud once to validate it; a failure here cannot happen, and is
// refused like one at the boundary if it does.
void MapNode::on_cloud(const cdc_msg_KeyframeCloud& m) {
  const std::string err = dds::compact::unpack_points(m.packed_points._buffer, m.packed_points._length, m.point_count,
                                                      m.resolution_m, cloud_);
  if (!err.empty()) {
    service_.boundary().refuse(dds::topics::kKeyframeCloud, dds::Validation::fail("packed_points: " + err));
    return;
  }
  core_.add_keyframe(m.robot_id, m.keyframe_id, cloud_);
}

void MapNode::on_poses(const cdc_msg_OptimizedPoses& m) {
  pose_list_.clear();
  for (uint32_t i = 0; i < m.poses._length; ++i) {
    pose_list_.emplace_back(m.poses._buffer[i].keyframe_id, dds::to_eigen(m.poses._buffer[i].pose));
  }
  core_.set_poses(m.robot_id, pose_list_);
}

void MapNode::write() {
  core_.write_pcd((dir_ / "map.pcd").string());
  core_.write_octomap((dir_ / "map.bt").string());
  ++writes_;
  spdlog::info("wrote {} and {}: {} keyframes placed", (dir_ / "map.pcd").string(), (dir_ / "map.bt").string(),
               core_.placed_keyframes());
}

nlohmann::json MapNode::stats() const {
  const MapStats& s = core_.stats();
  return {{"keyframes", s.keyframes},       {"placed", core_.placed_keyframes()},   {"placements", s.placements},
          {"pose_updates", s.pose_updates}, {"octree_rebuilds", s.octree_rebuilds}, {"writes", writes_}};
}

void MapNode::finish() {
  write();
  runtime::write_stats(service_, stats());
}

}  // namespace cdc::map
