// Synthetic inputs for the unit tests of the loop-closure core's parts, cheap to make (no
// simulator): Scan Contexts of numbered places, and clouds of a street-like scene.
#pragma once

#include "cdc/lidar/scan_context.hpp"
#include "cdc/loop_closure/loop_types.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

namespace cdc::loops::test {

// A descriptor that carries only its robot and keyframe id (for ordering and queueing tests).
inline DescriptorIn desc(uint32_t robot, uint32_t id) {
  DescriptorIn d;
  d.robot = robot;
  d.id = id;
  return d;
}

// Place `place` seen turned by `shift` sectors: every fifth cell or so occupied, at a height drawn
// from the place number, so that two places are far apart in Scan Context distance.
inline lidar::ScanContext place_context(uint32_t place, int shift = 0, int rings = 20, int sectors = 60) {
  std::mt19937 rng(1000 + place);
  std::uniform_real_distribution<float> height(0.5f, 6.0f), occupied(0.0f, 1.0f);
  lidar::ScanContext sc;
  sc.rings = rings;
  sc.sectors = sectors;
  sc.cells.assign(static_cast<size_t>(rings * sectors), 0.0f);
  for (int r = 0; r < rings; ++r) {
    for (int s = 0; s < sectors; ++s) {
      const float h = height(rng);
      if (occupied(rng) < 0.2f) sc.cells[static_cast<size_t>(r * sectors + (s + shift + sectors) % sectors)] = h;
    }
  }
  lidar::compute_ring_key(sc);
  return sc;
}

// A street-like scene around a sensor at the origin, from `seed`: a ground patch 1.8 m below it,
// walls at several headings and poles, ~8,000 points.
inline std::vector<Eigen::Vector3f> street_scene(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Eigen::Vector3f> cloud;
  for (double x = -20; x <= 20; x += 1.0) {
    for (double y = -20; y <= 20; y += 1.0) cloud.emplace_back(x, y, -1.8);
  }
  for (int w = 0; w < 6; ++w) {
    const double bearing = 2 * M_PI * (w + u(rng)) / 6, range = 8 + 12 * u(rng), heading = M_PI * u(rng);
    const Eigen::Vector2d centre(range * std::cos(bearing), range * std::sin(bearing));
    const Eigen::Vector2d along(std::cos(heading), std::sin(heading));
    for (double s = -6; s <= 6; s += 0.3) {
      for (double z = -1.8; z <= 4; z += 0.3) {
        const Eigen::Vector2d p = centre + s * along;
        cloud.emplace_back(p.x(), p.y(), z);
      }
    }
  }
  for (int k = 0; k < 10; ++k) {
    const double bearing = 2 * M_PI * u(rng), range = 4 + 16 * u(rng);
    for (double z = -1.8; z <= 3; z += 0.2) {
      for (int a = 0; a < 8; ++a) {
        cloud.emplace_back(range * std::cos(bearing) + 0.2 * std::cos(a * M_PI / 4),
                           range * std::sin(bearing) + 0.2 * std::sin(a * M_PI / 4), z);
      }
    }
  }
  return cloud;
}

// `cloud` expressed in a frame whose pose in the cloud's frame is T (points x -> T^-1 x).
inline std::vector<Eigen::Vector3f> seen_from(const std::vector<Eigen::Vector3f>& cloud, const Eigen::Isometry3d& T) {
  const Eigen::Isometry3f T_inv = T.inverse().cast<float>();
  std::vector<Eigen::Vector3f> out;
  out.reserve(cloud.size());
  for (const Eigen::Vector3f& p : cloud) out.push_back(T_inv * p);
  return out;
}

// A pose on the ground plane: (x, y) and heading.
inline Eigen::Isometry3d planar(double x, double y, double yaw_rad) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, 0);
  return T;
}

}  // namespace cdc::loops::test
