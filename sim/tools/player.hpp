// Dataset players: publish a cdc-sim dataset (or a real KITTI velodyne folder) over DDS.
#pragma once

#include <cstdint>
#include <string>

namespace cdc::sim {

struct PlayOptions {
  uint32_t domain = 0;
  std::string dds_config;
  double rate = 1.0;               // 1: real time; 2: twice as fast; 0: as fast as possible
  bool lockstep = false;           // wait for each robot's consumer before its next scan
  double lockstep_timeout_s = 30;  // give up when a consumer does not report progress
  uint32_t wait_readers = 0;       // LiDAR readers to wait for before starting
  uint32_t incarnation = 1;
  int64_t sweep_duration_ns = 100'000'000;  // of sweeps with per-point times (the dataset's sweep period)
  size_t max_scans = 0;                     // per robot; 0: all
  int only_robot = -1;                      // >= 0: play only this robot's sensors (a player beside each robot)
  std::string clock_file;                   // non-empty: after each sweep, "<sweep stamp ns> <sweeps played>" is
                                            // written here (atomically replaced), for a launcher that follows sim time
};

struct PlaySummary {
  size_t scans = 0;
  size_t imu_samples = 0;
  size_t radio_states = 0;  // radio timeline instants published on cdc/sim/radio
};

// Plays a dataset folder (`cdc-sim generate`, `cdc-import`). Throws std::runtime_error naming what is missing.
PlaySummary play_dataset(const std::string& dir, const PlayOptions& options);

}  // namespace cdc::sim
