// A simulated drive for the front-end core's tests: a road from rest up to a speed, winding, in a
// generated city, swept by a simulated VLP-16 with real motion distortion.
#pragma once

#include "cdc/frontend/frontend_core.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/trajectory.hpp"
#include "cdc/sim/world.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

namespace cdc::frontend {

// A drive from rest up to `speed` (in 2 s) along a road that winds at up to `yaw_rate`.
struct Drive {
  sim::SplineTrajectory traj;
  sim::World world;
  sim::LidarModel lidar = sim::LidarModel::vlp16();
  std::mt19937_64 rng{2};
  Drive(double speed, double yaw_rate, double duration) {
    std::vector<Eigen::Isometry3d> controls;
    std::vector<Eigen::Vector3d> path;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().z() = 1.73;
    for (int i = 0; i < static_cast<int>(duration * 10) + 40; ++i) {
      controls.push_back(T);
      path.push_back(T.translation());
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      step.translation().x() = speed * 0.1 * std::min(1.0, i / 20.0);
      step.linear() =
          Eigen::AngleAxisd(yaw_rate * 0.1 * std::sin(0.05 * i), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      T = T * step;
    }
    traj = sim::SplineTrajectory(controls, 0.0, 0.1);
    sim::WorldOptions wo;
    wo.seed = 12;
    wo.spacing_m = 8;
    world = sim::World::generate({path}, wo);
  }
  std::vector<ScanPoint> sweep(double t0) {
    std::vector<ScanPoint> out;
    for (const auto& p : sim::sweep(
             world, lidar, [&](double t) { return traj.pose(t0 + t); }, rng)) {
      out.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
    }
    return out;
  }
};

}  // namespace cdc::frontend
