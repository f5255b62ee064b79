// cdc-map: the map service. Keyframe clouds of every robot and the central optimiser's latest
// poses -> a global point cloud (.pcd) and an OctoMap (.bt), written on SIGUSR1, every
// --write-period-s and at shutdown.
#include "cdc/config/reader.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/map/map_core.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>

namespace {

using namespace cdc;
std::atomic<bool> g_write_requested{false};  // SIGUSR1, taken by ShutdownSignal's thread

struct Options {
  uint32_t robots = 3, central_id = 200, domain = 0;
  std::string dds_config, out_dir = ".", stats_out, log_level = "info";
  double write_period_s = 0;
  map::MapParams core;
};

void load(const std::string& path, Options& o) {
  config::Reader r(path);
  auto positive = [](const double& v) { return v > 0; };
  int robots = static_cast<int>(o.robots), central = static_cast<int>(o.central_id);
  r.get<int>("robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  r.get<int>("central_id", central, [](const int& v) { return v >= 0 && v <= 254; }, "0..254");
  r.get<double>("cloud_voxel_m", o.core.voxel_m, positive, "> 0");
  r.get<double>("octree_resolution_m", o.core.octree_resolution_m, positive, "> 0");
  r.get<double>("max_range_m", o.core.max_range_m, positive, "> 0");
  r.get<double>("ray_spacing_m", o.core.ray_spacing_m, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<double>("write_period_s", o.write_period_s, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<std::string>("log_level", o.log_level);
  r.finish();
  o.robots = static_cast<uint32_t>(robots);
  o.central_id = static_cast<uint32_t>(central);
}

int run(const Options& o) {
  dds::ParticipantOptions po;
  po.domain_id = o.domain;
  po.config = o.dds_config;
  dds::Participant participant(po);
  dds::Topic<cdc_msg_Keyframe> t_kf(participant, dds::topics::kKeyframe);
  dds::Topic<cdc_msg_OptimizedPoses> t_opt(participant, dds::topics::kCentralOptimized);
  dds::Reader<cdc_msg_Keyframe> r_kf(participant, t_kf, dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader()));
  dds::Reader<cdc_msg_OptimizedPoses> r_opt(participant, t_opt, dds::qos::monitored_reader().partitions(dds::partitions::all_robots_reader()));
  dds::GuardCondition stop(participant);
  dds::ShutdownSignal::add_guard(&stop);
  dds::ReadCondition rc_kf(r_kf.handle()), rc_opt(r_opt.handle());
  dds::WaitSet ws(participant);
  ws.attach(stop.handle(), 0);
  ws.attach(rc_kf.handle(), 1);
  ws.attach(rc_opt.handle(), 2);
  dds::ValidationLimits limits;
  limits.robot_count = o.robots;
  limits.extra_node_ids = {o.central_id};
  dds::RejectionCounter rejected;
  map::MapCore core(o.core);
  std::vector<Eigen::Vector3f> cloud;
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;
  uint64_t writes = 0;
  auto last_write = std::chrono::steady_clock::now();
  const std::filesystem::path dir(o.out_dir);
  std::filesystem::create_directories(dir);
  auto write = [&] {
    core.write_pcd((dir / "map.pcd").string());
    core.write_octomap((dir / "map.bt").string());
    ++writes;
    spdlog::info("wrote {} and {}: {} keyframes placed", (dir / "map.pcd").string(), (dir / "map.bt").string(),
                 core.placed_keyframes());
  };
  spdlog::info("map service up: cloud voxel {} m, OctoMap resolution {} m, writing to {}", o.core.voxel_m,
               o.core.octree_resolution_m, o.out_dir);
  while (!dds::ShutdownSignal::requested()) {
    ws.wait(std::chrono::milliseconds(200));
    r_kf.take(64).for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
      if (rejected.record(dds::topics::kKeyframe, dds::validate(m, limits))) {
        spdlog::warn("rejected keyframe: {}", rejected.last_reason());
        return;
      }
      cloud.clear();
      for (uint32_t i = 0; i < m.cloud._length; ++i) cloud.emplace_back(m.cloud._buffer[i].x, m.cloud._buffer[i].y, m.cloud._buffer[i].z);
      core.add_keyframe(m.robot_id, m.keyframe_id, cloud);
    });
    r_opt.take(16).for_each_valid([&](const cdc_msg_OptimizedPoses& m, const dds_sample_info_t&) {
      if (rejected.record(dds::topics::kCentralOptimized, dds::validate(m, limits))) {
        spdlog::warn("rejected optimised poses: {}", rejected.last_reason());
        return;
      }
      poses.clear();
      for (uint32_t i = 0; i < m.poses._length; ++i) poses.emplace_back(m.poses._buffer[i].keyframe_id, dds::to_eigen(m.poses._buffer[i].pose));
      core.set_poses(m.robot_id, poses);
    });
    const bool periodic = o.write_period_s > 0 && std::chrono::steady_clock::now() - last_write >= std::chrono::duration<double>(o.write_period_s);
    if (g_write_requested.exchange(false) || periodic) {
      write();
      last_write = std::chrono::steady_clock::now();
    }
  }
  dds::ShutdownSignal::remove_guard(&stop);
  write();
  if (!o.stats_out.empty()) {
    const map::MapStats& s = core.stats();
    nlohmann::json j{{"keyframes", s.keyframes},     {"placed", core.placed_keyframes()}, {"placements", s.placements},
                     {"pose_updates", s.pose_updates}, {"octree_rebuilds", s.octree_rebuilds}, {"writes", writes},
                     {"rejected", rejected.by_topic()}};
    j["topics"] = dds::topic_traffic_json();
    std::ofstream(o.stats_out) << j.dump(2) << '\n';
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  dds::ShutdownSignal::install();
  dds::ShutdownSignal::on_user_signal([](int signal) {
    if (signal == SIGUSR1) g_write_requested = true;
  });
  CLI::App app{
      "cdc-map: the map service. Places every robot's keyframe clouds (cdc/frontend/keyframe) with the central\n"
      "optimiser's latest poses (cdc/central/optimized) into a global point cloud and an OctoMap; writes\n"
      "OUT/map.pcd and OUT/map.bt on SIGUSR1, every write_period_s and at shutdown (SIGINT/SIGTERM)."};
  Options o;
  std::string config_path, log_level;
  int domain = -1;
  app.add_option("--config", config_path, "YAML configuration (see services/map/config)")->check(CLI::ExistingFile);
  app.add_option("--out", o.out_dir, "output folder")->capture_default_str();
  app.add_option("--dds-config", o.dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--stats-out", o.stats_out, "write counters (JSON) here at shutdown");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  try {
    load(config_path, o);
    o.domain = domain >= 0 ? static_cast<uint32_t>(domain) : dds::domain_from_env(0);
    if (!log_level.empty()) o.log_level = log_level;
    runtime::init_logging("cdc-map", o.log_level);
    return run(o);
  } catch (const config::ConfigError& e) {
    std::cerr << "cdc-map: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-map: " << e.what() << '\n';
    return 1;
  }
}
