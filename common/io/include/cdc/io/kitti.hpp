// KITTI-derived multi-robot trajectories, in the spirit of the CDC-SLAM paper: a sequence's ground
// truth, turned into the LiDAR frame, cut into K overlapping pieces that play back at the same time.
#pragma once

#include "cdc/geometry/trajectory.hpp"

#include <filesystem>
#include <string>
#include <vector>

namespace cdc::io {

// Reads `key` (e.g. "Tr_04_10") from a calib_Tr.txt file: a row-major 3x4 T_cam0_velo.
Eigen::Isometry3d read_kitti_calib(const std::string& path, const std::string& key);

// The LiDAR's trajectory of a KITTI sequence: T = inv(Tr) * T_world_cam0(i) * Tr, so that the first
// pose is the identity and z points up; stamps i * 0.1 s.
geometry::Trajectory kitti_lidar_trajectory(const std::string& poses_path, const Eigen::Isometry3d& Tr);

struct SplitOptions {
  int robots = 3;
  double overlap = 0.15;      // fraction of a piece shared with the next piece
  double time_shift_s = 0.0;  // robot k starts k * time_shift_s after robot 0
  // Robots that drive their piece the other way: from its last pose to its first, heading turned
  // by 180 deg about the sensor's z, moved reverse_lane_m to the left of the sequence's direction
  // (the opposite lane). Their places then meet the other robots' (and the sequence's own revisits)
  // driving the other way.
  std::vector<int> reverse;
  double reverse_lane_m = 0.0;  // [m]
};

// The index ranges [first, last) of a sequence of n samples that split_robots gives each robot.
struct IndexRange {
  size_t first = 0, last = 0;
};
std::vector<IndexRange> split_ranges(size_t n, const SplitOptions& options);

// Cuts a trajectory into `robots` consecutive pieces of equal length, each sharing `overlap` of
// itself with the next (so that neighbouring robots cover common ground), and re-times every piece
// to start at k * time_shift_s: the robots drive simultaneously. Poses stay in the sequence's
// world frame (robot 0's first pose is its origin only if the sequence's is). A robot in
// options.reverse drives its piece backwards in time with its heading turned (SplitOptions::reverse).
// Throws std::invalid_argument for a reversed robot that is not one of the robots.
std::vector<geometry::Trajectory> split_robots(const geometry::Trajectory& sequence, const SplitOptions& options);

enum class KittiPosesFrame {
  kCamera,  // KITTI odometry ground truth: T_world_cam0, turned into the LiDAR frame with Tr
  kLidar,   // already the LiDAR's pose in the world (many real sets ship it so)
};

struct KittiSequenceOptions {
  std::filesystem::path times;  // default: DIR/times.txt when present, else frame * period_ns
  std::filesystem::path poses;  // optional 3x4 row-major poses, one line per frame
  KittiPosesFrame poses_frame = KittiPosesFrame::kCamera;
  std::filesystem::path calib;   // default: DIR/calib.txt (for camera-frame poses)
  std::string calib_key = "Tr";  // the entry of calib holding T_cam0_velo
  int64_t period_ns = 100'000'000;
  bool allow_gaps = false;  // accept missing frame numbers (else a missing sweep is an error)
};

// A KITTI odometry sequence folder (velodyne/NNNNNN.bin, times.txt, calib.txt) or a bare folder of
// NNNNNN.bin sweeps: the sweeps in frame order with their times and, when given, their LiDAR poses
// (stamped like the sweeps). Throws FormatError naming the file for a missing sweep, a times or poses
// file too short for the frames, or times that do not increase.
struct KittiSequence {
  std::vector<size_t> frames;                 // frame numbers
  std::vector<std::filesystem::path> sweeps;  // one .bin per frame
  std::vector<int64_t> stamps_ns;             // one per frame
  geometry::Trajectory poses;                 // LiDAR poses, one per frame, or empty
  size_t first_frame = 0;
  bool times_from_file = false;
};
KittiSequence read_kitti_sequence(const std::filesystem::path& dir, const KittiSequenceOptions& options = {});

}  // namespace cdc::io
