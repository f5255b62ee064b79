// A simulated world for the odometry tests: generated along a straight, slightly slanted path
// through the origin, and swept by a simulated LiDAR from given poses. Seeded: every run sees the
// same world and the same sweeps.
#pragma once

#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <random>
#include <vector>

namespace cdc::odometry::test {

struct SceneOptions {
  int path_points = 40;  // path points i = 0 .. path_points - 1
  double step_m = 1.0;   // x of point i: step_m * (i - path_points / 2)
  double slant_m = 0.2;  // y of point i: slant_m * i
  uint64_t world_seed = 9;
  double spacing_m = 6;  // between the world's objects
  sim::LidarModel lidar = sim::LidarModel::hdl64();
};

struct SimScene {
  sim::World world;
  sim::LidarModel lidar;
  std::mt19937_64 rng{4};

  explicit SimScene(const SceneOptions& o) : lidar(o.lidar) {
    std::vector<Eigen::Vector3d> path;
    for (int i = 0; i < o.path_points; ++i) {
      path.emplace_back(o.step_m * i - o.step_m * (o.path_points / 2), o.slant_m * i, 1.73);
    }
    sim::WorldOptions wo;
    wo.seed = o.world_seed;
    wo.spacing_m = o.spacing_m;
    world = sim::World::generate({path}, wo);
  }

  // One sweep from the still pose T, in the sensor frame; each point's ring into `rings` when given.
  std::vector<Eigen::Vector3d> scan(const Eigen::Isometry3d& T, std::vector<uint16_t>* rings = nullptr) {
    std::vector<Eigen::Vector3d> out;
    for (const auto& p : sim::sweep(
             world, lidar, [&](double) { return T; }, rng)) {
      out.emplace_back(p.x, p.y, p.z);
      if (rings != nullptr) rings->push_back(p.ring);
    }
    return out;
  }
};

}  // namespace cdc::odometry::test
