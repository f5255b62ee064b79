// DDS shell of the map service: every robot's keyframe clouds (packed, cdc/map/keyframe_cloud) and the central
// optimiser's latest poses in; OUT/map.pcd and OUT/map.bt written on request (SIGUSR1), every write period and at
// shutdown. The map is MapCore's.
#pragma once

#include "map_config.hpp"

#include "cdc/dds/types.hpp"
#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <vector>

namespace cdc::map {

class MapNode {
 public:
  // SIGUSR1 has the map written (dds::ShutdownSignal's user signal handler, while the node lives).
  MapNode(const runtime::ServiceOptions& common, const MapNodeOptions& options);
  ~MapNode();
  // Works until shutdown is asked for.
  void spin();
  nlohmann::json stats() const;
  // Writes the map and --stats-out.
  void finish();

 private:
  void on_cloud(const cdc_msg_KeyframeCloud& m);
  void on_poses(const cdc_msg_OptimizedPoses& m);
  void write();

  MapNodeOptions o_;
  std::filesystem::path dir_;
  std::atomic<bool> write_requested_{false};  // set on the signal thread, cleared by spin()
  runtime::Service service_;
  runtime::Input<cdc_msg_KeyframeCloud> clouds_;
  runtime::Input<cdc_msg_OptimizedPoses> poses_;
  MapCore core_;
  uint64_t writes_ = 0;
  std::chrono::steady_clock::time_point last_write_;
  std::vector<Eigen::Vector3f> cloud_;
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> pose_list_;
};

}  // namespace cdc::map
