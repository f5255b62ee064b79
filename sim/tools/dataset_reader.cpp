#include "dataset_reader.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>

namespace cdc::sim {
namespace fs = std::filesystem;
namespace {

std::vector<char> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) {
    throw std::runtime_error(p.string() + ": cannot open");
  }
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

std::vector<DatasetImu> read_dataset_imu(const fs::path& p) {
  std::ifstream in(p);
  if (!in) {
    throw std::runtime_error(p.string() + ": cannot open");
  }
  std::vector<DatasetImu> out;
  std::string line;
  size_t n = 0;
  std::getline(in, line);
  ++n;
  while (std::getline(in, line)) {
    ++n;
    double t, a[3], g[3];
    if (std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &t, a, a + 1, a + 2, g, g + 1, g + 2) != 7) {
      throw std::runtime_error(p.string() + ":" + std::to_string(n) + ": expected t,ax,ay,az,gx,gy,gz");
    }
    out.push_back({static_cast<int64_t>(std::llround(t * 1e9)), Eigen::Vector3d(a[0], a[1], a[2]), Eigen::Vector3d(g[0], g[1], g[2])});
  }
  return out;
}

std::vector<DatasetScan> list_dataset_scans(const std::string& dir, size_t max_scans,
                                            std::map<uint32_t, geometry::Trajectory>* groundtruth) {
  std::vector<DatasetScan> scans;
  for (uint32_t r = 0;; ++r) {
    const fs::path rd = fs::path(dir) / ("robot_" + std::to_string(r));
    if (!fs::is_directory(rd)) {
      if (r == 0) throw std::runtime_error(rd.string() + ": missing (no robot folders in " + dir + ")");
      break;
    }
    const std::vector<int64_t> times = geometry::read_times((rd / "times.txt").string());
    const geometry::Trajectory gt = geometry::read_tum((rd / "groundtruth.tum").string());
    for (size_t k = 0; k < times.size() && (max_scans == 0 || k < max_scans); ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.bin", k);
      DatasetScan s{times[k], r, k, rd / "velodyne" / name, rd / "velodyne_meta" / name, std::nullopt};
      if (k < gt.size()) s.truth = gt[k].pose;
      scans.push_back(std::move(s));
    }
    if (groundtruth != nullptr) (*groundtruth)[r] = gt;
  }
  std::stable_sort(scans.begin(), scans.end(), [](const DatasetScan& a, const DatasetScan& b) { return a.stamp_ns < b.stamp_ns; });
  return scans;
}

std::vector<DatasetPoint> read_dataset_scan(const fs::path& bin, const fs::path& meta_path) {
  const std::vector<char> xyzi = read_bytes(bin);
  if (xyzi.size() % 16 != 0) {
    throw std::runtime_error(bin.string() + ": size " + std::to_string(xyzi.size()) + " is not a multiple of 16 bytes");
  }
  const size_t n = xyzi.size() / 16;
  std::vector<char> meta;
  if (!meta_path.empty()) {
    meta = read_bytes(meta_path);
    if (meta.size() != n * 8) {
      throw std::runtime_error(meta_path.string() + ": " + std::to_string(meta.size() / 8) + " entries for " +
                               std::to_string(n) + " points");
    }
  }
  std::vector<DatasetPoint> pts(n);
  for (size_t i = 0; i < n; ++i) {
    float v[4];
    std::memcpy(v, xyzi.data() + 16 * i, 16);
    DatasetPoint& p = pts[i];
    p.x = v[0];
    p.y = v[1];
    p.z = v[2];
    p.intensity = v[3];
    if (!meta.empty()) {
      std::memcpy(&p.time_offset, meta.data() + 8 * i, 4);
      std::memcpy(&p.ring, meta.data() + 8 * i + 4, 2);
    } else {
      const double az = std::atan2(static_cast<double>(v[1]), static_cast<double>(v[0]));
      p.time_offset = static_cast<float>(0.1 * (az + M_PI) / (2 * M_PI));
    }
  }
  return pts;
}

}  // namespace cdc::sim
