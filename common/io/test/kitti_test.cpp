#include "cdc/io/kitti.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

namespace cdc::io {
namespace {

std::string data() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr ? env : "../shared/data";
}

TEST(KittiSplit, SyntheticSequenceTilesWithTheRequestedOverlap) {
  geometry::Trajectory seq;
  for (int i = 0; i < 1000; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(i, 0, 0);
    seq.push_back({i * 100'000'000LL, T});
  }
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
  EXPECT_THROW(split_robots(seq, SplitOptions{3, 1.0, 0}), std::invalid_argument);
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
  const auto robots = split_robots(seq, SplitOptions{3, 0.15, 0.0});
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
