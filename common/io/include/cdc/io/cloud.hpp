// Point clouds on disk: KITTI .bin sweeps (float32 x, y, z, intensity), the dataset layout's
// per-point side file (float32 time offset, uint16 ring, uint16 zero), PCD and PLY.
#pragma once

#include "cdc/io/error.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <vector>

namespace cdc::io {

// One LiDAR return in the sensor frame.
struct CloudPoint {
  float x = 0, y = 0, z = 0;
  float intensity = 0;
  float time_offset = 0;  // [s] since the sweep start (meaningful only when the sweep has times)
  uint16_t ring = 0;      // beam index (meaningful only when the sweep has rings)
};

// A sweep as read from a file, with what the file told about its points.
struct Sweep {
  std::vector<CloudPoint> points;
  bool has_time = false;       // per-point time offsets present
  bool has_ring = false;       // per-point ring present
  bool has_intensity = false;  // intensity present
};

// KITTI .bin: float32 x, y, z, intensity per point. Throws FormatError naming the file when its size
// is not a multiple of 16 bytes.
std::vector<CloudPoint> read_kitti_bin(const std::filesystem::path& path);
void write_kitti_bin(const std::filesystem::path& path, const std::vector<CloudPoint>& points);

// The dataset layout's side file: per point float32 time offset [s], uint16 ring, uint16 zero.
// Fills time_offset and ring of `points`; throws naming the file when the count differs.
void read_point_meta(const std::filesystem::path& path, std::vector<CloudPoint>& points);
void write_point_meta(const std::filesystem::path& path, const std::vector<CloudPoint>& points);

// A sweep from a cloud file by its extension: .bin (KITTI), .pcd (ascii, binary or binary_compressed;
// the io library's own reader) or .ply (PCL's reader); the fields x, y, z and, when present,
// intensity, ring and a per-point time under their common names, as for a ROS PointCloud2, others
// skipped. Throws FormatError naming the file and, for a PCD, the line or byte offset.
Sweep read_cloud_file(const std::filesystem::path& path);
bool is_cloud_file(const std::filesystem::path& path);  // .bin, .pcd or .ply
// x, y, z of a cloud file's points (read_cloud_file), for registering saved sweeps.
std::vector<Eigen::Vector3d> read_cloud_xyz(const std::filesystem::path& path);

}  // namespace cdc::io
