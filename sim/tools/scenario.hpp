// Scenario files (YAML) and dataset generation for cdc-sim.
#pragma once

#include "cdc/sim/lidar.hpp"
#include "cdc/sim/missions.hpp"
#include "cdc/sim/radio.hpp"
#include "cdc/sim/world.hpp"

#include <Eigen/Geometry>

#include <functional>
#include <string>
#include <vector>

namespace cdc::sim {

struct Scenario {
  std::string name = "scenario";
  uint64_t seed = 1;
  std::string source = "kitti";       // kitti | procedural
  std::string kitti_sequence = "05";  // poses file <data>/kitti/poses/<seq>.txt
  std::string calib_key = "Tr_04_10";
  int robots = 3;
  double overlap = 0.15;
  double time_shift_s = 0;
  std::vector<int> reverse;     // robots that drive their KITTI piece the other way (io::SplitOptions::reverse)
  double reverse_lane_m = 0;    // how far to the left of the sequence's direction they drive [m]
  MissionOptions mission;       // procedural
  std::string lidar = "vlp16";  // vlp16 | hdl64
  double lidar_elevation_error_deg = 0;  // sigma of each beam's (fixed, seeded) elevation calibration error
  double lidar_elevation_bias_deg = 0;   // an elevation error common to every beam (KITTI's HDL-64E has about 0.22 deg)
  double lidar_azimuth_error_deg = 0;    // sigma of each beam's (fixed, seeded) azimuth calibration error
  double lidar_range_offset_m = 0;       // sigma of each beam's (fixed, seeded) distance offset
  bool lidar_per_robot = false;          // each robot's LiDAR has calibration errors of its own (else one shared draw)
  double imu_rate_hz = 200;
  double duration_s = 0;  // 0: the whole trajectories
  int central_robot = 0;  // the central rides on this robot; -1: fixed position
  Eigen::Vector3d central_position = Eigen::Vector3d::Zero();
  uint32_t central_id = 200;
  double central_range_m = 150;  // CR_0
  double robot_range_m = 150;
  RadioOptions radio;
  WorldOptions world;
};

// Reads a scenario; throws config::ConfigError naming every bad or unknown field.
Scenario load_scenario(const std::string& path);

// The scenario's LiDAR with its calibration errors (per-beam elevation, azimuth and distance errors drawn from
// the seed, and the common elevation bias).
// robot: whose unit, when the scenario gives each robot its own (lidar_per_robot); otherwise ignored.
LidarModel scenario_lidar(const Scenario& s, int robot = 0);

struct GenerateOptions {
  std::string data_dir;        // reference data (KITTI poses and calibration)
  size_t max_scans = 0;        // per robot; 0: all
  std::function<bool()> stop;  // asked between sweeps and radio steps when set: true throws Stopped
};

struct GenerateSummary {
  size_t robots = 0;
  size_t scans = 0;
  size_t points = 0;
  size_t out_of_range_periods = 0;
};

// The radio's out-of-range periods for a scenario, without simulating any sensor (fast).
std::vector<OutOfRangePeriod> scenario_radio_periods(const Scenario& scenario, const GenerateOptions& options);

// Writes the dataset folder (see sim/README.md). Throws std::runtime_error naming the path on I/O
// problems or missing reference data.
GenerateSummary generate_dataset(const Scenario& scenario, const std::string& scenario_path, const std::string& out_dir,
                                 const GenerateOptions& options);

}  // namespace cdc::sim
