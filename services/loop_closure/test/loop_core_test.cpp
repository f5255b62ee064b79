// The loop-closure core end to end on simulated scans, offline (one core holds every cloud): two
// robots drive the same block; every loop it publishes is true (1 m / 5 deg), and it finds the
// robots' shared places; own-robot candidates the odometry puts far away are never verified.
#include "cdc/loop_closure/loop_core.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"
#include "circle_lap.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <random>
#include <tuple>
#include <vector>

namespace cdc::loops {
namespace {

using test::circle_lap;

TEST(LoopCore, FindsTrueLoopsBetweenTwoRobotsOnTheSameBlock) {
  // Robots 0 and 1 drive the same circle (40 m radius), robot 1 a little behind; keyframes every 2 m.
  const auto [lap, world] = circle_lap(40, 70);  // 140 m
  const sim::LidarModel lidar = sim::LidarModel::vlp16();
  std::mt19937_64 rng(1);

  LoopParams params;
  LoopCore core(params);
  LoopParams unlevelled = params;  // the same loops with the registration's information as it is
  unlevelled.tilt_information_scale = 1.0;
  LoopCore raw_core(unlevelled);
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::vector<LoopOut> published;
  std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>, graph::Matrix6d> raw_information;
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
      kf.T_odom = T;  // a levelled odometry's tilt
      for (const auto& p : sim::sweep(
               world, lidar, [&](double) { return T; }, rng))
        kf.cloud.emplace_back(p.x, p.y, p.z);
      truth[{r, kf.id}] = T;
      for (const auto& l : raw_core.add_keyframe(kf)) {
        raw_information[{l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b}] = l.information;
      }
      for (const auto& l : core.add_keyframe(std::move(kf))) published.push_back(l);
    }
  }
  size_t inter = 0;
  double chi2_t = 0;
  for (const auto& l : published) {
    ASSERT_FALSE(l.withdrawn);
    const Eigen::Isometry3d gt = truth.at({l.robot_a, l.keyframe_a}).inverse() * truth.at({l.robot_b, l.keyframe_b});
    const Eigen::Isometry3d e = gt.inverse() * l.T_a_b;
    EXPECT_LT(e.translation().norm(), 1.0)
        << l.robot_a << "/" << l.keyframe_a << " - " << l.robot_b << "/" << l.keyframe_b;
    EXPECT_LT(Eigen::AngleAxisd(e.rotation()).angle(), 5 * M_PI / 180);
    // The registration's information, levelled: about the query keyframe's horizontal axes the
    // rotation information is scaled by tilt_information_scale, about its vertical axis it is kept.
    const auto raw = raw_information.find({l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b});
    ASSERT_NE(raw, raw_information.end()) << "the same loop without levelling";
    const Eigen::Vector3d up = truth.at({l.robot_b, l.keyframe_b}).linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d side = up.cross(Eigen::Vector3d::UnitX()).normalized(), ahead = side.cross(up);
    const Eigen::Matrix3d info_r = l.information.bottomRightCorner<3, 3>(),
                          raw_r = raw->second.bottomRightCorner<3, 3>();
    EXPECT_NEAR(up.dot(info_r * up), up.dot(raw_r * up), 1e-6 * up.dot(raw_r * up));
    EXPECT_NEAR(side.dot(info_r * side), params.tilt_information_scale * side.dot(raw_r * side),
                1e-6 * side.dot(raw_r * side));
    EXPECT_NEAR(ahead.dot(info_r * ahead), params.tilt_information_scale * ahead.dot(raw_r * ahead),
                1e-6 * ahead.dot(raw_r * ahead));
    EXPECT_TRUE((l.information.topLeftCorner<3, 3>().isApprox(raw->second.topLeftCorner<3, 3>(), 1e-9)))
        << "translation untouched";
    // The registration's translation information (the loop's / loop_information_scale) matches its error.
    const Eigen::Vector3d dt = l.T_a_b.translation() - gt.translation();
    chi2_t += dt.dot(l.information.topLeftCorner<3, 3>() * dt) / params.loop_information_scale;
    inter += l.robot_a != l.robot_b ? 1 : 0;
  }
  const double mean_chi2_t = chi2_t / static_cast<double>(std::max<size_t>(published.size(), 1));
  std::printf("translation error against its information: mean chi2 %.2f (3 DoF)\n", mean_chi2_t);
  // Neither over- nor under-confident by more than 3x in variance (3 if exact).
  EXPECT_GT(mean_chi2_t, 1.0);
  EXPECT_LT(mean_chi2_t, 9.0);
  std::printf("%zu loops published (%zu inter-robot), %llu verified, %llu failed verification\n", published.size(),
              inter, static_cast<unsigned long long>(core.stats().verified),
              static_cast<unsigned long long>(core.stats().verification_failed));
  EXPECT_GE(inter, 10u);
}

// One robot drives 1.75 laps of a circle of 20 m radius. With its true odometry the second lap closes loops with the
// first; with odometry that has it climbing 0.5 m per keyframe (30 m up after a lap, beyond the
// gate of 15 m + 5 % of the 125 m driven), those candidates are never verified.
TEST(LoopCore, OwnCandidatesTheOdometryPutsFarAwayAreNotVerified) {
  const auto [lap, world] = circle_lap(20, 110);  // a 126 m lap
  const sim::LidarModel lidar = sim::LidarModel::vlp16();
  auto run = [&](double climb_m, double gate_m = 15) {
    std::mt19937_64 rng(1);
    LoopParams params;
    params.intra_gate_m = gate_m;
    LoopCore core(params);
    size_t intra = 0;
    Eigen::Isometry3d prev = Eigen::Isometry3d::Identity();
    for (size_t k = 0; k * 10 < lap.size(); ++k) {
      const Eigen::Isometry3d T = lap[k * 10].pose;
      KeyframeIn kf;
      kf.id = static_cast<uint32_t>(k);
      kf.T_prev = prev.inverse() * T;
      kf.T_prev.translation().z() += climb_m;
      prev = T;
      kf.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
      for (const auto& p : sim::sweep(
               world, lidar, [&](double) { return T; }, rng))
        kf.cloud.emplace_back(p.x, p.y, p.z);
      for (const auto& l : core.add_keyframe(std::move(kf))) intra += l.robot_a == l.robot_b ? 1 : 0;
    }
    return std::make_pair(intra, core.stats());
  };
  const auto [true_loops, true_stats] = run(0.0);
  const auto [climb_loops, climb_stats] = run(0.5);
  std::printf("true odometry: %zu loops, %llu verified; climbing: %zu loops, %llu verified, %llu gated\n", true_loops,
              static_cast<unsigned long long>(true_stats.verified), climb_loops,
              static_cast<unsigned long long>(climb_stats.verified),
              static_cast<unsigned long long>(climb_stats.intra_gated));
  EXPECT_GE(true_loops, 5u);
  EXPECT_EQ(climb_loops, 0u);
  EXPECT_EQ(climb_stats.verified, 0u);
  EXPECT_GT(climb_stats.intra_gated, 0u);
}

}  // namespace
}  // namespace cdc::loops
