// Two or three simulated robots on one 40 m circle, for the loop-closure core's tests as a robot's
// service runs it: their keyframes, clouds and descriptors, fed in the order the service sees them.
#pragma once

#include "cdc/loop_closure/loop_core.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"
#include "circle_lap.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <utility>
#include <vector>

namespace cdc::loops {

// `robots` robots on one 40 m circle, 8 m apart; keyframes every 2 m with their true clouds.
struct Circle {
  sim::World world;
  geometry::Trajectory lap;
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::map<std::pair<uint32_t, uint32_t>, std::vector<Eigen::Vector3f>> clouds;
  Circle(double duration_s, uint32_t robots) {
    cdc::test::CircleLap l = cdc::test::circle_lap(40, duration_s);
    lap = std::move(l.lap);
    world = std::move(l.world);
    std::mt19937_64 rng(1);
    for (uint32_t r = 0; r < robots; ++r) {
      for (uint32_t k = 0; k * 10 + 40 * r < lap.size(); ++k) {
        const Eigen::Isometry3d T = lap[k * 10 + 40 * r].pose;
        truth[{r, k}] = T;
        auto& c = clouds[{r, k}];
        for (const auto& p : sim::sweep(
                 world, sim::LidarModel::vlp16(), [&](double) { return T; }, rng))
          c.emplace_back(p.x, p.y, p.z);
      }
    }
  }
  DescriptorIn descriptor(uint32_t r, uint32_t k, const LoopParams& p) const {
    return DescriptorIn{r, k, wire_form(lidar::make_scan_context(clouds.at({r, k}), p.scan_context)), truth.at({r, k})};
  }
  KeyframeIn keyframe(uint32_t r, uint32_t k) const {
    KeyframeIn kf;
    kf.robot = r;
    kf.id = k;
    if (k > 0) kf.T_prev = truth.at({r, k - 1}).inverse() * truth.at({r, k});
    kf.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
    kf.cloud = clouds.at({r, k});
    return kf;
  }
  // Robot 1's service at step k: robot 0's descriptor k (a reverse search), then robot 1's keyframe k
  // and its descriptor.
  LoopEvents feed_step(LoopCore& core, uint32_t k, const LoopParams& p, Nanos now) const {
    LoopEvents ev = core.add_descriptor(descriptor(0, k, p), now);
    ev.append(core.add_keyframe_data(keyframe(1, k), now));
    ev.append(core.add_descriptor(descriptor(1, k, p), now));
    return ev;
  }
  void expect_true(const LoopOut& l) const {
    const Eigen::Isometry3d e =
        (truth.at({l.robot_a, l.keyframe_a}).inverse() * truth.at({l.robot_b, l.keyframe_b})).inverse() * l.T_a_b;
    EXPECT_LT(e.translation().norm(), 1.0);
    EXPECT_LT(Eigen::AngleAxisd(e.rotation()).angle(), 5 * M_PI / 180);
  }
};

}  // namespace cdc::loops
