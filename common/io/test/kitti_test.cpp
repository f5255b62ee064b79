#include "cdc/io/kitti.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

namespace cdc::io {
namespace {

SplitOptions pieces(int robots, double overlap) {
  SplitOptions o;
  o.robots = robots;
  o.overlap = overlap;
  return o;
}

// 1000 poses 1 m apart along x, one every 0.1 s.
geometry::Trajectory straight_sequence() {
  geometry::Trajectory seq;
  for (int i = 0; i < 1000; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(i, 0, 0);
    seq.push_back({i * 100'000'000LL, T});
  }
  return seq;
}

std::string data() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr ? env : "../shared/data";
}

TEST(KittiSplit, SyntheticSequenceTilesWithTheRequestedOverlap) {
  const geometry::Trajectory seq = straight_sequence();
  SplitOptions o;
  o.robots = 3;
  o.overlap = 0.2;
  o.time_shift_s = 2.0;
  const auto r = split_robots(seq, o);
  ASSERT_EQ(r.size(), 3u);
  // piece = 1000 / (3 - 2 * 0.2) = 384.6: starts 0, 307, 615; each shares ~77 poses with the next.
  EXPECT_EQ(r[0].front().pose.translation().x(), 0);
  EXPECT_EQ(r[1].front().pose.translation().x(), 307);
  EXPECT_EQ(r[2].front().pose.translation().x(), 615);
  EXPECT_EQ(r[2].back().pose.translation().x(), 999);
  EXPECT_GT(r[0].back().pose.translation().x(), r[1].front().pose.translation().x() + 70);
  EXPECT_EQ(r[1].front().stamp_ns, 2'000'000'000);
  EXPECT_EQ(r[2].front().stamp_ns, 4'000'000'000);
  EXPECT_THROW(split_robots(seq, pieces(3, 1.0)), std::invalid_argument);
}

TEST(KittiSplit, AReversedRobotDrivesItsPieceBackwardsOnTheOppositeLane) {
  const geometry::Trajectory seq = straight_sequence();
  SplitOptions o;
  o.reverse = {1};
  o.reverse_lane_m = 3.5;
  const auto r = split_robots(seq, o);
  ASSERT_EQ(r.size(), 3u);
  const auto forward = split_robots(seq, SplitOptions{});
  ASSERT_EQ(r[1].size(), forward[1].size());
  // Same times, places in the other order, heading along -x, 3.5 m to the left of the +x drive.
  EXPECT_EQ(r[1].front().stamp_ns, forward[1].front().stamp_ns);
  EXPECT_EQ(r[1].back().stamp_ns, forward[1].back().stamp_ns);
  EXPECT_NEAR(r[1].front().pose.translation().x(), forward[1].back().pose.translation().x(), 1e-9);
  EXPECT_NEAR(r[1].back().pose.translation().x(), forward[1].front().pose.translation().x(), 1e-9);
  EXPECT_NEAR(r[1].front().pose.translation().y(), 3.5, 1e-9);
  EXPECT_NEAR((r[1].front().pose.linear() * Eigen::Vector3d::UnitX()).x(), -1.0, 1e-9);
  EXPECT_NEAR((r[1].front().pose.linear() * Eigen::Vector3d::UnitZ()).z(), 1.0, 1e-9);
  // It moves along its own +x: forward, not in reverse gear.
  const Eigen::Vector3d step = r[1].front().pose.inverse() * r[1][1].pose.translation();
  EXPECT_GT(step.x(), 0.9);
  // The other robots are untouched.
  EXPECT_TRUE(r[0].back().pose.isApprox(forward[0].back().pose));
  EXPECT_TRUE(r[2].front().pose.isApprox(forward[2].front().pose));
  o.reverse = {3};
  EXPECT_THROW(split_robots(seq, o), std::invalid_argument);
}

TEST(KittiSplit, Sequence05GivesThreeRobotsThatShareGroundAndTime) {
  const std::string poses = data() + "/kitti/poses/05.txt", calib = data() + "/kitti/calib_Tr.txt";
  if (!std::filesystem::exists(poses) || !std::filesystem::exists(calib)) {
    GTEST_SKIP() << "reference data absent: " << poses << " or " << calib << " not found";
  }
  const auto seq = kitti_lidar_trajectory(poses, read_kitti_calib(calib, "Tr_04_10"));
  ASSERT_EQ(seq.size(), 2761u);
  // In the LiDAR frame the vehicle drives along +x with z up: the first seconds go forward in x.
  EXPECT_GT(seq[50].pose.translation().x(), 10.0);
  EXPECT_LT(std::abs(seq[50].pose.translation().z()), 2.0);
  const auto robots = split_robots(seq, pieces(3, 0.15));
  ASSERT_EQ(robots.size(), 3u);
  // Common places: every robot passes within 5 m of a place another robot also visits.
  for (size_t a = 0; a < 3; ++a) {
    size_t shared = 0;
    for (const auto& p : robots[a]) {
      bool near = false;
      for (size_t b = 0; b < 3 && !near; ++b) {
        if (b == a) continue;
        for (const auto& q : robots[b]) {
          if ((p.pose.translation() - q.pose.translation()).norm() < 5.0) {
            near = true;
            break;
          }
        }
      }
      shared += near ? 1 : 0;
    }
    std::printf("robot %zu: %zu poses, %zu within 5 m of another robot's path\n", a, robots[a].size(), shared);
    EXPECT_GT(shared, 50u) << "robot " << a;
  }
  // Time windows overlap: all three drive at the same time.
  for (const auto& r : robots) {
    EXPECT_EQ(r.front().stamp_ns, 0);
    EXPECT_GT(r.back().stamp_ns, 60'000'000'000LL);
  }
}

}  // namespace
}  // namespace cdc::io
