// cdc-frontend: a robot's LiDAR(-inertial) odometry service.
#include "frontend_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-frontend: the robot's LiDAR(-inertial) odometry. Subscribes its sweeps (cdc/sensor/lidar), IMU\n"
      "(cdc/sensor/imu) and the back-end's corrections (cdc/backend/correction); publishes odometry at scan rate\n"
      "(cdc/frontend/odometry, corrections fused in without jumps), keyframes (cdc/frontend/keyframe) and its\n"
      "progress for lock-step playback. Stops cleanly on SIGINT/SIGTERM."};
  std::string config_path, dds_config, stats_out, trajectory_out, log_level;
  int domain = -1;
  uint32_t robot = 0;
  bool lidar_only = false;
  app.add_option("--robot", robot, "this robot's id")->required()->check(CLI::Range(0, 254));
  app.add_option("--config", config_path, "YAML configuration (see services/frontend/config)")->check(CLI::ExistingFile);
  app.add_option("--dds-config", dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  int sensor_domain = -1;
  app.add_option("--sensor-domain", sensor_domain,
                 "DDS domain of the sweeps, IMU and lock-step progress (default: the SLAM domain)")
      ->check(CLI::Range(0, 232));
  std::string sensor_dds_config;
  app.add_option("--sensor-dds-config", sensor_dds_config,
                 "Cyclone DDS configuration of the sensor domain (default: as --dds-config)");
  app.add_flag("--lidar-only", lidar_only, "ignore the IMU");
  bool no_corrections = false;
  app.add_flag("--no-corrections", no_corrections,
               "ignore the back-end's corrections: publish raw odometry (the paper's 'without correction' ablation)");
  int imu_wait_ms = -1;
  app.add_option("--imu-wait-ms", imu_wait_ms,
                 "a sweep waits at most this long for the IMU to reach its end (default 100; lock-step playback,\n"
                 "where the IMU always comes, can wait longer so that a busy machine never changes the result)")
      ->check(CLI::Range(0, 60000));
  app.add_option("--trajectory-out", trajectory_out, "write the published odometry (TUM) here at shutdown");
  app.add_option("--stats-out", stats_out, "write counters (JSON) here at shutdown");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  try {
    cdc::frontend::FrontendNodeOptions o = cdc::frontend::load_frontend_options(config_path);
    if (robot >= o.robots) {
      std::cerr << "cdc-frontend: --robot " << robot << " is not one of the " << o.robots << " robots of the configuration\n";
      return 2;
    }
    o.robot = robot;
    o.domain = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
    o.dds_config = dds_config;
    o.sensor_domain = sensor_domain;
    o.sensor_dds_config = sensor_dds_config;
    o.stats_out = stats_out;
    o.trajectory_out = trajectory_out;
    if (lidar_only) o.use_imu = false;
    if (no_corrections) o.take_corrections = false;
    if (imu_wait_ms >= 0) o.imu_wait = std::chrono::milliseconds(imu_wait_ms);
    if (!log_level.empty()) o.log_level = log_level;
    cdc::runtime::init_logging("cdc-frontend-" + std::to_string(robot), o.log_level);
    return cdc::frontend::run_frontend(o);
  } catch (const cdc::config::ConfigError& e) {
    std::cerr << "cdc-frontend: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-frontend: " << e.what() << '\n';
    return 1;
  }
}
