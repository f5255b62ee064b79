// cdc-frontend: a robot's LiDAR(-inertial) odometry service.
#include "frontend_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

namespace {

struct FrontendFlags {
  int sensor_domain = -1;
  std::string sensor_dds_config, trajectory_out;
  bool lidar_only = false, no_corrections = false;
  int imu_wait_ms = -1, sequence_wait_ms = -1;
};

void add_options(CLI::App& app, FrontendFlags& f) {
  app.add_option("--sensor-domain", f.sensor_domain,
                 "DDS domain of the sweeps, IMU and lock-step progress (default: the SLAM domain)")
      ->check(CLI::Range(0, 232));
  app.add_option("--sensor-dds-config", f.sensor_dds_config,
                 "Cyclone DDS configuration of the sensor domain (default: as --dds-config)");
  app.add_flag("--lidar-only", f.lidar_only, "ignore the IMU");
  app.add_flag("--no-corrections", f.no_corrections,
               "ignore the back-end's corrections: publish raw odometry (the paper's 'without correction' ablation)");
  app.add_option("--imu-wait-ms", f.imu_wait_ms,
                 "a sweep waits at most this long for the IMU to reach its end (default 100; lock-step playback,\n"
                 "where the IMU always comes, can wait longer so that a busy machine never changes the result)")
      ->check(CLI::Range(0, 60000));
  app.add_option("--sequence-wait-ms", f.sequence_wait_ms,
                 "the first sweep waits at most this long for the back-end's keyframe sequence, which a restarted\n"
                 "front-end continues (default 2000; without an answer a new sequence starts)")
      ->check(CLI::Range(0, 60000));
  app.add_option("--trajectory-out", f.trajectory_out, "write the published odometry (TUM) here at shutdown");
}

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-frontend",
      "the robot's LiDAR(-inertial) odometry. Subscribes its sweeps (cdc/sensor/lidar), IMU\n"
      "(cdc/sensor/imu) and the back-end's corrections (cdc/backend/correction); publishes odometry at scan rate\n"
      "(cdc/frontend/odometry, corrections fused in without jumps), keyframes (cdc/frontend/keyframe) and its\n"
      "progress for lock-step playback. Stops cleanly on SIGINT/SIGTERM.",
      "see services/frontend/config", rt::kRobotOption | rt::kStatsOption};
  rt::ServiceOptions common;
  FrontendFlags f;
  return rt::service_main(
      argc, argv, spec, common, [&](CLI::App& app) { add_options(app, f); },
      [&] {
        cdc::frontend::FrontendNodeOptions o = cdc::frontend::load_frontend_options(common.config);
        common.check_robot(o.robots);
        o.robot = common.robot;
        o.domain = common.domain_id();
        o.dds_config = common.dds_config;
        o.sensor_domain = f.sensor_domain;
        o.sensor_dds_config = f.sensor_dds_config;
        o.stats_out = common.stats_out;
        o.trajectory_out = f.trajectory_out;
        if (f.lidar_only) o.use_imu = false;
        if (f.no_corrections) o.take_corrections = false;
        if (f.imu_wait_ms >= 0) o.imu_wait = std::chrono::milliseconds(f.imu_wait_ms);
        if (f.sequence_wait_ms >= 0) o.sequence_wait = std::chrono::milliseconds(f.sequence_wait_ms);
        return rt::run_node<cdc::frontend::FrontendNode>(spec, common, o.log_level, o);
      });
}
