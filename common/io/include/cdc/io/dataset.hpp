// The dataset layout every cdc-slam tool reads (cdc-sim play, cdc-launch, cdc-odometry, cdc-loops,
// cdc-experiment), whether the sweeps were simulated or imported from a real recording:
//
//   DIR/dataset.json            what the dataset is (see DatasetInfo)
//   DIR/radio.csv               link states over time (t,a,b,in_range,distance,loss); radio_periods.csv
//   DIR/robot_K/times.txt       sweep start [s], one line per sweep
//   DIR/robot_K/velodyne/NNNNNN.bin        float32 x, y, z, intensity per point (sensor frame)
//   DIR/robot_K/velodyne_meta/NNNNNN.bin   per point float32 time offset [s], uint16 ring, uint16 zero;
//                                          absent when the sweeps carry no per-point times
//   DIR/robot_K/groundtruth.tum  LiDAR pose at each sweep start (ground truth or reference poses; optional)
//   DIR/robot_K/imu.csv          t,ax,ay,az,gx,gy,gz (optional)
//   DIR/robot_K/calib.yaml       T_lidar_imu (optional)
#pragma once

#include "cdc/geometry/trajectory.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/error.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cdc::io {

// Where the per-point times of a dataset's sweeps come from.
enum class PointTimes {
  kSensor,   // measured per point (simulator, driver, a bag's time field): sweeps need deskewing
  kAzimuth,  // derived from each point's azimuth at import (a spinning sensor without time fields)
  kNone,     // none: the sweeps are already motion-compensated, every point at the sweep's stamp
};
const char* to_string(PointTimes t);
std::optional<PointTimes> parse_point_times(const std::string& s);

// dataset.json.
struct DatasetInfo {
  std::string name = "dataset";
  std::string source = "simulated";  // simulated | kitti | sweeps | rosbag1 | rosbag2 | ...
  size_t robots = 0;
  size_t scans = 0;
  size_t points = 0;
  uint32_t central_id = 200;
  size_t out_of_range_periods = 0;
  PointTimes point_times = PointTimes::kSensor;
  double sweep_period_s = 0.1;         // nominal time between sweeps
  std::string radio = "simulated";     // simulated | reference_poses | timeline | none: where radio.csv comes from
  std::string poses = "ground_truth";  // ground_truth | reference | none: what groundtruth.tum holds
};

// Reads dataset.json; fields it lacks keep their defaults (older simulated datasets). Throws FormatError
// naming the file on bad JSON or bad values.
DatasetInfo read_dataset_info(const std::filesystem::path& dir);
void write_dataset_info(const std::filesystem::path& dir, const DatasetInfo& info);

struct DatasetScan {
  int64_t stamp_ns = 0;  // sweep start
  uint32_t robot = 0;
  uint64_t seq = 0;
  std::filesystem::path bin, meta;         // meta empty: the sweep has no per-point times or rings
  std::optional<Eigen::Isometry3d> truth;  // LiDAR pose at the sweep start
};

struct DatasetImu {
  int64_t stamp_ns = 0;
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // specific force [m/s^2]
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // [rad/s]
};

// imu.csv of a robot folder (header, then t,ax,ay,az,gx,gy,gz); an absent file is no IMU. Throws
// naming file:line.
std::vector<DatasetImu> read_dataset_imu(const std::filesystem::path& csv);

// T_lidar_imu from a robot's calib.yaml; identity when the file is absent.
Eigen::Isometry3d read_dataset_calib(const std::filesystem::path& yaml);

// Every robot's scans (robot_0, robot_1, ... until the first missing folder), merged in time order;
// at most max_scans per robot (0: all). Fills `groundtruth` per robot when given (empty where the
// robot has no groundtruth.tum). Throws std::runtime_error naming the path when the folder is not a
// dataset, or when a listed sweep file is missing.
std::vector<DatasetScan> list_dataset_scans(const std::string& dir, size_t max_scans = 0,
                                            std::map<uint32_t, geometry::Trajectory>* groundtruth = nullptr);

// A scan's points with their times and rings when the scan has a meta file (has_time and has_ring
// set), else without (both false: nothing is invented). Throws FormatError naming the file on bad sizes.
Sweep read_dataset_scan(const DatasetScan& scan);

// Writes a dataset folder safely: everything goes into DIR.partial first and is renamed to DIR by
// commit(), so an import that fails half-way leaves no folder that looks like a dataset. A writer
// destroyed without commit() removes its partial folder.
class DatasetWriter {
 public:
  // Throws when DIR exists and overwrite is false.
  explicit DatasetWriter(std::filesystem::path dir, bool overwrite = false);
  ~DatasetWriter();
  DatasetWriter(const DatasetWriter&) = delete;
  DatasetWriter& operator=(const DatasetWriter&) = delete;

  // Appends robot `robot`'s next sweep (sweeps of a robot come in time order). Writes the meta file when
  // the sweep has times or rings.
  void add_sweep(uint32_t robot, int64_t stamp_ns, const Sweep& sweep);
  void set_groundtruth(uint32_t robot, const geometry::Trajectory& poses);
  void set_imu(uint32_t robot, const std::vector<DatasetImu>& imu);
  void set_calib(uint32_t robot, const Eigen::Isometry3d& T_lidar_imu, const std::string& lidar_name,
                 double imu_rate_hz);
  // radio.csv content (header included) and the out-of-range periods CSV (a,b,start,end).
  void set_radio(const std::string& radio_csv, const std::string& periods_csv);
  // Writes every robot's times.txt and dataset.json (robots, scans and points counted here), then
  // renames the folder into place. Returns the final DatasetInfo.
  DatasetInfo commit(DatasetInfo info);

  const std::filesystem::path& partial_dir() const { return partial_; }
  size_t sweeps(uint32_t robot) const;

 private:
  std::filesystem::path robot_dir(uint32_t robot) const;

  std::filesystem::path dir_, partial_;
  bool overwrite_ = false, committed_ = false;
  std::map<uint32_t, std::vector<int64_t>> stamps_;
  size_t points_ = 0;
};

}  // namespace cdc::io
