#include "cdc/sim/kitti.hpp"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace cdc::sim {

Eigen::Isometry3d read_kitti_calib(const std::string& path, const std::string& key) {
  std::ifstream in(path);
  if (!in) {
    throw std::runtime_error(path + ": cannot open calibration file");
  }
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    std::istringstream s(line);
    std::string k;
    if (!(s >> k) || k != key) {
      continue;
    }
    double v[12];
    for (double& x : v) {
      if (!(s >> x)) {
        throw std::runtime_error(path + ":" + std::to_string(n) + ": " + key + " needs 12 numbers");
      }
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    T.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
    return T;
  }
  throw std::runtime_error(path + ": no entry '" + key + "'");
}

geometry::Trajectory kitti_lidar_trajectory(const std::string& poses_path, const Eigen::Isometry3d& Tr) {
  geometry::Trajectory cam = geometry::read_kitti(poses_path, nullptr, 100'000'000);
  const Eigen::Isometry3d Tr_inv = Tr.inverse();
  for (auto& sp : cam) {
    sp.pose = Tr_inv * sp.pose * Tr;
  }
  return cam;
}

std::vector<geometry::Trajectory> split_robots(const geometry::Trajectory& seq, const SplitOptions& o) {
  if (o.robots < 1 || o.overlap < 0 || o.overlap >= 1) {
    throw std::invalid_argument("split: robots must be >= 1 and overlap in [0, 1)");
  }
  const double n = static_cast<double>(seq.size());
  const double piece = n / (o.robots - (o.robots - 1) * o.overlap);  // pieces tile the sequence
  std::vector<geometry::Trajectory> out;
  for (int k = 0; k < o.robots; ++k) {
    const size_t first = static_cast<size_t>(std::floor(k * piece * (1 - o.overlap)));
    const size_t last = std::min(seq.size(), static_cast<size_t>(std::ceil(static_cast<double>(first) + piece)));
    if (last <= first + 3) {
      throw std::invalid_argument("split: pieces too short for " + std::to_string(o.robots) + " robots");
    }
    geometry::Trajectory t(seq.begin() + static_cast<std::ptrdiff_t>(first), seq.begin() + static_cast<std::ptrdiff_t>(last));
    const int64_t base = t.front().stamp_ns;
    const int64_t shift = static_cast<int64_t>(std::llround(k * o.time_shift_s * 1e9));
    for (auto& sp : t) {
      sp.stamp_ns = sp.stamp_ns - base + shift;
    }
    out.push_back(std::move(t));
  }
  return out;
}

}  // namespace cdc::sim
