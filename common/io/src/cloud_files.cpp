// Cloud files by extension: KITTI .bin, PCD (the io library's own reader) and PLY (PCL's reader), the
// latter two decoded like a ROS PointCloud2 (one place for field layouts).
#include "cdc/io/cloud.hpp"
#include "cdc/io/ros_messages.hpp"
#include "pcd.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/io/ply_io.h>

#include <string>

namespace cdc::io {
namespace fs = std::filesystem;

namespace {

// A PLY file through PCL's reader, laid out as a PointCloud2.
PointCloud2Msg read_ply(const fs::path& path) {
  pcl::PCLPointCloud2 blob;
  const int rc = pcl::io::loadPLYFile(path.string(), blob);
  if (rc < 0) throw FormatError(path.string() + ": PCL cannot read it as ply (code " + std::to_string(rc) + ")");
  PointCloud2Msg m;
  m.header.stamp_ns = static_cast<int64_t>(blob.header.stamp) * 1000;  // PCL stamps are microseconds
  m.header.frame_id = blob.header.frame_id;
  m.height = blob.height;
  m.width = blob.width;
  for (const pcl::PCLPointField& f : blob.fields) {
    m.fields.push_back({f.name, f.offset, f.datatype, f.count});
  }
  m.is_bigendian = blob.is_bigendian != 0;
  m.point_step = blob.point_step;
  m.row_step = blob.row_step;
  m.data = std::move(blob.data);
  m.is_dense = blob.is_dense != 0;
  return m;
}

}  // namespace

bool is_cloud_file(const fs::path& path) {
  const std::string ext = path.extension().string();
  return ext == ".bin" || ext == ".pcd" || ext == ".ply";
}

Sweep read_cloud_file(const fs::path& path) {
  const std::string ext = path.extension().string();
  if (ext == ".bin") {
    Sweep s;
    s.points = read_kitti_bin(path);
    s.has_intensity = true;
    return s;
  }
  if (ext != ".pcd" && ext != ".ply") throw FormatError(path.string() + ": not a .bin, .pcd or .ply cloud");
  if (!fs::is_regular_file(path)) throw FormatError(path.string() + ": cannot open");
  const PointCloud2Msg m = ext == ".pcd" ? detail::read_pcd(path) : read_ply(path);
  try {
    return static_cast<Sweep>(cloud_points(m));
  } catch (const FormatError& e) {
    throw FormatError(path.string() + ": " + e.what());
  }
}

std::vector<Eigen::Vector3d> read_cloud_xyz(const fs::path& path) {
  const Sweep s = read_cloud_file(path);
  std::vector<Eigen::Vector3d> out;
  out.reserve(s.points.size());
  for (const CloudPoint& p : s.points) out.emplace_back(p.x, p.y, p.z);
  return out;
}

}  // namespace cdc::io
