// Reading a cdc-sim dataset folder (layout in sim/README.md) without DDS: the scans of every
// robot in time order, their points with per-point times, and the ground truth. Used by the
// players and by the offline tools (cdc-loops, cdc-odometry).
#pragma once

#include "cdc/geometry/trajectory.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cdc::sim {

struct DatasetPoint {
  float x = 0, y = 0, z = 0, intensity = 0;
  float time_offset = 0;  // [s] since the sweep start
  uint16_t ring = 0;
};

struct DatasetScan {
  int64_t stamp_ns = 0;   // sweep start
  uint32_t robot = 0;
  uint64_t seq = 0;
  std::filesystem::path bin, meta;  // meta empty: time offsets from azimuth (real KITTI)
  std::optional<Eigen::Isometry3d> truth;  // LiDAR pose at the sweep start
};

struct DatasetImu {
  int64_t stamp_ns = 0;
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // specific force [m/s^2]
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // [rad/s]
};

// imu.csv of a robot folder (header, then t,ax,ay,az,gx,gy,gz); throws naming file:line.
std::vector<DatasetImu> read_dataset_imu(const std::filesystem::path& csv);

// Every robot's scans (robot_0, robot_1, ... until the first missing folder), merged in time
// order; at most max_scans per robot (0: all). Fills `groundtruth` per robot when given. Throws
// std::runtime_error naming the path when the folder is not a dataset.
std::vector<DatasetScan> list_dataset_scans(const std::string& dir, size_t max_scans = 0,
                                            std::map<uint32_t, geometry::Trajectory>* groundtruth = nullptr);

// A scan's points: float32 x, y, z, intensity per point, and from the meta file float32 time
// offset, uint16 ring, uint16 zero per point (or times from azimuth for a counter-clockwise 0.1 s
// sweep starting behind the sensor when there is none). Throws naming the file on bad sizes.
std::vector<DatasetPoint> read_dataset_scan(const std::filesystem::path& bin, const std::filesystem::path& meta);

}  // namespace cdc::sim
