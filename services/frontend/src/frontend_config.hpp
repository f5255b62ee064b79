// The front-end's configuration (services/frontend/config/frontend.yaml), shared by the
// cdc-frontend node and the offline cdc-odometry tool; no DDS here. The node's robot, domain and
// statistics file are the shared options' (runtime::ServiceOptions).
#pragma once

#include "cdc/frontend/frontend_core.hpp"

#include <chrono>
#include <string>

namespace cdc::frontend {

struct FrontendNodeOptions {
  uint32_t robots = 3;
  int sensor_domain = -1;  // >= 0: sweeps, IMU and progress on this domain (the simulator's)
  std::string trajectory_out, log_level = "info";
  std::string sensor_dds_config;  // configuration of the sensor domain; empty: as the SLAM domain's
  FrontendParams core;
  bool use_imu = true;
  bool take_corrections = true;  // false: the back-end's corrections are ignored (an ablation)
  double imu_gap_s = 0.05;       // a larger gap between IMU samples is reported and bridged by constant velocity
  std::chrono::milliseconds imu_wait{100};  // a sweep waits this long at most for the IMU to reach its end
  // The first sweep waits this long at most for the back-end to say where the robot's keyframe
  // sequence stands (cdc/backend/sequence); without an answer the front-end starts a new sequence.
  std::chrono::milliseconds sequence_wait{2000};
  uint32_t max_scan_points = 500'000;
};

// Reads a frontend.yaml (empty path: the defaults); every invalid key is named in the exception.
FrontendNodeOptions load_frontend_options(const std::string& path);

}  // namespace cdc::frontend
