// KITTI-derived multi-robot trajectories, in the spirit of the CDC-SLAM paper: a sequence's ground
// truth, turned into the LiDAR frame, cut into K overlapping pieces that play back at the same time.
#pragma once

#include "cdc/geometry/trajectory.hpp"

#include <string>
#include <vector>

namespace cdc::sim {

// Reads `key` (e.g. "Tr_04_10") from a calib_Tr.txt file: a row-major 3x4 T_cam0_velo.
Eigen::Isometry3d read_kitti_calib(const std::string& path, const std::string& key);

// The LiDAR's trajectory of a KITTI sequence: T = inv(Tr) * T_world_cam0(i) * Tr, so that the first
// pose is the identity and z points up; stamps i * 0.1 s.
geometry::Trajectory kitti_lidar_trajectory(const std::string& poses_path, const Eigen::Isometry3d& Tr);

struct SplitOptions {
  int robots = 3;
  double overlap = 0.15;        // fraction of a piece shared with the next piece
  double time_shift_s = 0.0;    // robot k starts k * time_shift_s after robot 0
};

// Cuts a trajectory into `robots` consecutive pieces of equal length, each sharing `overlap` of
// itself with the next (so that neighbouring robots cover common ground), and re-times every piece
// to start at k * time_shift_s: the robots drive simultaneously. Poses stay in the sequence's
// world frame (robot 0's first pose is its origin only if the sequence's is).
std::vector<geometry::Trajectory> split_robots(const geometry::Trajectory& sequence, const SplitOptions& options);

}  // namespace cdc::sim
