// cdc-import's core: real recordings into the dataset layout (cdc/io/dataset.hpp) that every tool
// reads, with a radio timeline so that cdc-launch and cdc-experiment run on them unchanged.
#pragma once

#include "cdc/io/dataset.hpp"
#include "cdc/io/kitti.hpp"
#include "cdc/sim/radio.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace cdc::sim {

// How the radio of an imported run is made. With poses (ground truth or reference), the link states
// follow the true distances as in a simulated run; without, an out-of-range timeline file gives them;
// with neither, every link stays in range.
struct ImportRadio {
  int central_robot = 0;  // the central rides on this robot; -1: fixed position
  Eigen::Vector3d central_position = Eigen::Vector3d::Zero();
  uint32_t central_id = 200;
  double central_range_m = 0;  // CR_0; 0: not given (required with poses and several robots)
  double robot_range_m = 0;    // 0: the central's range
  RadioOptions options;
  std::filesystem::path timeline;  // CSV a,b,start,end [s] of out-of-range periods
};

struct ImportOptions {
  std::filesystem::path out;
  bool overwrite = false;
  std::string name;         // dataset name (default: the output folder's name)
  int robots = 1;           // split into this many simultaneously driving robots (the paper's protocol)
  double overlap = 0.15;    // fraction of a piece shared with the next
  double time_shift_s = 0;  // robot k starts k * time_shift_s after robot 0
  size_t max_scans = 0;     // per robot; 0: all
  ImportRadio radio;
};

struct ImportSummary {
  io::DatasetInfo info;
  size_t skipped = 0;              // input items skipped (counted, each reported on stderr by the tool)
  std::vector<std::string> notes;  // what the importer decided (point times, radio source, ...)
};

// One recording as a sequence of sweeps on one sensor, before splitting.
struct Recording {
  std::string source;                             // kitti | sweeps | rosbag1 | rosbag2
  std::vector<int64_t> stamps_ns;                 // per sweep
  std::vector<std::filesystem::path> files;       // per sweep, when sweeps are files
  std::vector<std::filesystem::path> meta_files;  // per sweep, beside files, when sweeps carry times
  std::shared_ptr<void> scratch;                  // keeps a temporary folder of extracted sweeps alive
  geometry::Trajectory poses;                     // per sweep (LiDAR in the world), or empty
  std::string poses_kind = "none";                // ground_truth | reference | none
  std::vector<io::DatasetImu> imu;                // the recording's IMU, or empty
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();
  io::PointTimes point_times = io::PointTimes::kNone;
  double sweep_period_s = 0.1;
  std::vector<std::string> notes;
  size_t skipped = 0;

  size_t size() const { return stamps_ns.size(); }
  io::Sweep sweep(size_t i) const;  // reads a file-backed sweep
};

// A KITTI odometry sequence (or a bare velodyne folder). point_times: kNone (the sweeps taken as
// motion-compensated) or kAzimuth (times from each point's azimuth, a counter-clockwise sweep of one period
// starting behind the sensor, as the HDL-64E spins).
Recording kitti_recording(const std::filesystem::path& dir, const io::KittiSequenceOptions& options,
                          io::PointTimes point_times, const std::string& poses_kind);

// A folder of .bin/.pcd/.ply sweeps in name order, with times (times.txt beside them, one per sweep, or
// the period) and optional poses (3x4 KITTI lines in the LiDAR frame, or TUM). Missing numbered sweeps are
// an error.
struct SweepFolderOptions {
  std::filesystem::path times;  // default DIR/times.txt, else index * period
  std::filesystem::path poses;  // KITTI 3x4 (LiDAR frame) or TUM, detected by its columns
  std::string poses_kind = "reference";
  double period_s = 0.1;
};
Recording sweep_folder_recording(const std::filesystem::path& dir, const SweepFolderOptions& options);

// Poses of the LiDAR at the recording's sweeps: KITTI 3x4 lines (one per sweep) or a TUM file
// interpolated at the sweep stamps (a sweep outside its span is an error). kind: reference or ground_truth.
void attach_poses(Recording& recording, const std::filesystem::path& poses, const std::string& kind);

// A ROS 1 or ROS 2 bag (db3, MCAP): the LiDAR topic (sensor_msgs/PointCloud2, or
// velodyne_msgs/VelodyneScan decoded with the sensor's calibration) and, when present, an IMU topic
// (sensor_msgs/Imu). Sweeps are extracted into `scratch_dir` (a folder the caller picks beside the
// output) and written from there. A message that does not decode is skipped and counted (the first few
// reasons in the notes); a damaged bag, a topic of another type or no decodable sweep at all is an error.
struct BagImportOptions {
  std::string lidar_topic;                     // default: the bag's only PointCloud2 or VelodyneScan topic
  std::string imu_topic;                       // default: the bag's only Imu topic; "none": ignore the IMU
  std::filesystem::path velodyne_calibration;  // VelodyneScan: the sensor's calibration (default: built-in table)
  std::string velodyne_model;  // VelodyneScan: VLP16, VLP32C, HDL32E, HDL64E (S2), HDL64E_S3, VLS128 (default: from the
                               // packets)
  double velodyne_scan_phase_deg = 0;  // where a Velodyne sweep is cut
  double min_range_m = 0.4, max_range_m = 200;
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();
  bool T_lidar_imu_given = false;
};
Recording bag_recording(const std::filesystem::path& bag, const BagImportOptions& options,
                        const std::filesystem::path& scratch_dir);

// Splits the recording into robots, writes sweeps, times, poses, IMU and the radio, and commits the
// dataset only when everything was written. Throws on any error (nothing is left behind).
ImportSummary write_import(const Recording& recording, const ImportOptions& options);

// Sweep times from azimuth for a sweep without time fields: counter-clockwise from behind the sensor
// over `period_s`.
void times_from_azimuth(io::Sweep& sweep, double period_s);

}  // namespace cdc::sim
