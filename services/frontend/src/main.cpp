// cdc-frontend: a robot's LiDAR(-inertial) odometry service.
#include "frontend_node.hpp"

#include "cdc/config/cli_range.hpp"
#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

namespace {

struct FrontendFlags {
  int sensor_domain = -1;
  std::string sensor_dds_config, trajectory_out;
  bool lidar_only = false, no_corrections = false;
  int imu_wait_ms = -1, sequence_wait_ms = -1;

  void declare(CLI::App& app) {
    app.add_option("--sensor-domain", sensor_domain,
                   "DDS domain of the sweeps, IMU and lock-step progress (default: the SLAM domain)")
        ->check(CLI::Range(0, 232));
    app.add_option("--sensor-dds-config", sensor_dds_config,
                   "Cyclone DDS configuration of the sensor domain (default: as --dds-config)");
    app.add_flag("--lidar-only", lidar_only, "ignore the IMU");
    app.add_flag("--no-corrections", no_corrections,
                 "ignore the back-end's corrections: publish raw odometry (the paper's 'without correction' ablation)");
    app.add_option("--imu-wait-ms", imu_wait_ms,
                   "a sweep waits at most this long for the IMU to reach its end (default 100; lock-step playback,\n"
                   "where the IMU always comes, can wait longer so that a busy machine never changes the result)")
        ->check(cdc::config::cli_range(0, 60000));
    app.add_option("--sequence-wait-ms", sequence_wait_ms,
                   "the first sweep waits at most this long for the back-end's keyframe sequence, which a restarted\n"
                   "front-end continues (default 2000; without an answer a new sequence starts)")
        ->check(cdc::config::cli_range(0, 60000));
    app.add_option("--trajectory-out", trajectory_out, "write the published odometry (TUM) here at shutdown");
  }
  void apply(cdc::frontend::FrontendNodeOptions& o, const cdc::runtime::ServiceOptions&) const {
    o.sensor_domain = sensor_domain;
    o.sensor_dds_config = sensor_dds_config;
    o.trajectory_out = trajectory_out;
    if (lidar_only) o.use_imu = false;
    if (no_corrections) o.take_corrections = false;
    if (imu_wait_ms >= 0) o.imu_wait = std::chrono::milliseconds(imu_wait_ms);
    if (sequence_wait_ms >= 0) o.sequence_wait = std::chrono::milliseconds(sequence_wait_ms);
  }
};

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{"cdc-frontend",
                             R"(the robot's LiDAR(-inertial) odometry. Subscribes its sweeps (cdc/sensor/lidar), IMU
(cdc/sensor/imu) and the back-end's corrections (cdc/backend/correction); publishes odometry at scan rate
(cdc/frontend/odometry, corrections fused in without jumps), keyframes (cdc/frontend/keyframe) and its
progress for lock-step playback. Stops cleanly on SIGINT/SIGTERM.)",
                             "see services/frontend/config", rt::kRobotOption | rt::kStatsOption};
  return rt::node_main<cdc::frontend::FrontendNode>(
      argc, argv, spec, cdc::frontend::load_frontend_options,
      [](const cdc::frontend::FrontendNodeOptions& o) { return o.robots; }, FrontendFlags{});
}
