// The loop-closure core end to end on simulated scans: two robots drive the same block; every loop it
// publishes is true (1 m / 5 deg), and it finds the robots' shared places.
#include "cdc/loop_closure/loop_core.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/missions.hpp"
#include "cdc/sim/world.hpp"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

namespace cdc::loops {
namespace {

TEST(LoopCore, FindsTrueLoopsBetweenTwoRobotsOnTheSameBlock) {
  // Robots 0 and 1 lap the same 40 m circle, robot 1 a little behind; keyframes every 2 m.
  sim::MissionOptions mo;
  mo.pattern = sim::MissionPattern::kLoops;
  mo.robots = 1;
  mo.size_m = 40;
  mo.speed_mps = 2;
  mo.duration_s = 70;  // 140 m: more than one lap
  const auto lap = sim::procedural_mission(mo).front();
  std::vector<Eigen::Vector3d> path;
  for (const auto& sp : lap) path.push_back(sp.pose.translation());
  sim::WorldOptions wo;
  wo.seed = 3;
  wo.spacing_m = 8;
  const sim::World world = sim::World::generate({path}, wo);
  const sim::LidarModel lidar = sim::LidarModel::vlp16();
  std::mt19937_64 rng(1);

  LoopParams params;
  LoopCore core(params);
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::vector<LoopOut> published;
  const size_t step = 10;  // 2 m at 2 m/s and 10 Hz
  for (size_t k = 0; k * step + 40 < lap.size(); ++k) {
    for (uint32_t r = 0; r < 2; ++r) {
      const size_t i = k * step + (r == 1 ? 40 : 0);  // robot 1 is 8 m further along the same path
      const Eigen::Isometry3d T = lap[i].pose;
      KeyframeIn kf;
      kf.robot = r;
      kf.id = static_cast<uint32_t>(k);
      if (k > 0) kf.T_prev = truth[{r, static_cast<uint32_t>(k - 1)}].inverse() * T;
      kf.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
      for (const auto& p : sim::sweep(world, lidar, [&](double) { return T; }, rng)) kf.cloud.emplace_back(p.x, p.y, p.z);
      truth[{r, kf.id}] = T;
      for (const auto& l : core.add_keyframe(std::move(kf))) published.push_back(l);
    }
  }
  size_t inter = 0;
  for (const auto& l : published) {
    ASSERT_FALSE(l.withdrawn);
    const Eigen::Isometry3d gt = truth.at({l.robot_a, l.keyframe_a}).inverse() * truth.at({l.robot_b, l.keyframe_b});
    const Eigen::Isometry3d e = gt.inverse() * l.T_a_b;
    EXPECT_LT(e.translation().norm(), 1.0) << l.robot_a << "/" << l.keyframe_a << " - " << l.robot_b << "/" << l.keyframe_b;
    EXPECT_LT(Eigen::AngleAxisd(e.rotation()).angle(), 5 * M_PI / 180);
    inter += l.robot_a != l.robot_b ? 1 : 0;
  }
  std::printf("%zu loops published (%zu inter-robot), %llu verified, %llu failed verification\n", published.size(), inter,
              static_cast<unsigned long long>(core.stats().verified),
              static_cast<unsigned long long>(core.stats().verification_failed));
  EXPECT_GE(inter, 10u);
}

}  // namespace
}  // namespace cdc::loops
