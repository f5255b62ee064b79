// Deskewing a sweep: each point moved to the sensor frame at the sweep's start along the motion
// over the sweep (constant velocity) or the IMU's rotation; crop to the range limits; a sweep
// without per-point times taken as it is; the points registered and their normals.
#include "cdc/frontend/deskewing.hpp"
#include "cdc/geometry/se3.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace cdc::frontend {
namespace {

constexpr double kSpan = 0.1;  // [s] a sweep's span

// The sensor's pose at time t of a sweep (relative to its start) moving by xi over kSpan.
Eigen::Isometry3d pose_at(const geometry::Vector6d& xi, double t) { return geometry::se3_exp(xi * (t / kSpan)); }

// Points of a static scene (start frame) seen by a moving sensor, each at one of the 65 instants
// the deskewing samples the motion at (k / 64 of the span); the last at the span's end.
struct MovingSweep {
  std::vector<Eigen::Vector3d> scene;
  std::vector<ScanPoint> points;
  MovingSweep(const geometry::Vector6d& xi, size_t n) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> r(5.0, 40.0), a(-M_PI, M_PI), z(-2.0, 5.0);
    std::uniform_int_distribution<int> slot(0, 63);
    for (size_t i = 0; i < n; ++i) {
      const double range = r(rng), angle = a(rng);
      scene.emplace_back(range * std::cos(angle), range * std::sin(angle), z(rng));
      const double t = i + 1 == n ? kSpan : kSpan * slot(rng) / 64.0;
      const Eigen::Vector3d seen = pose_at(xi, t).inverse() * scene.back();
      points.push_back({seen.cast<float>(), static_cast<float>(t), 0});
    }
  }
};

geometry::Vector6d drive_and_turn() {
  geometry::Vector6d xi;
  xi << 1.5, 0.1, 0.0, 0.0, 0.0, 0.3;  // 15 m/s, 3 rad/s over a sweep of 0.1 s
  return xi;
}

double worst_error(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, (a[i] - b[i]).norm());
  return worst;
}

TEST(Deskewing, MovesEachPointToTheSweepsStartAlongTheMotion) {
  const MovingSweep s(drive_and_turn(), 2000);
  const Deskewer deskewer{FrontendParams{}};
  std::vector<uint16_t> rings;
  // The motion over the sweep, from the motion between two sweeps 0.1 s apart.
  const Eigen::Isometry3d motion =
      Deskewer::motion_over(pose_at(drive_and_turn(), kSpan), latest_point_time(s.points), kSpan);
  const std::vector<Eigen::Vector3d> deskewed = deskewer.deskew(0, s.points, motion, DeskewImu{}, rings);
  ASSERT_EQ(deskewed.size(), s.scene.size());
  EXPECT_EQ(rings.size(), s.scene.size());
  std::vector<Eigen::Vector3d> raw;
  for (const auto& p : s.points) raw.push_back(p.p.cast<double>());
  EXPECT_GT(worst_error(raw, s.scene), 5.0) << "the scene as measured is smeared";
  EXPECT_LT(worst_error(deskewed, s.scene), 1e-4);
}

TEST(Deskewing, TheMotionOverASweepScalesTheMotionBetweenSweeps) {
  const Eigen::Isometry3d D = pose_at(drive_and_turn(), kSpan);
  EXPECT_TRUE(Deskewer::motion_over(D, 0.05F, 0.1).isApprox(pose_at(drive_and_turn(), 0.05), 1e-6));
  EXPECT_TRUE(Deskewer::motion_over(D, 0.1F, 0.2).isApprox(pose_at(drive_and_turn(), 0.05), 1e-6));
}

TEST(Deskewing, CropsToTheRangeLimits) {
  FrontendParams p;  // 1.5 to 100 m
  const Deskewer deskewer(p);
  const std::vector<ScanPoint> points = {{Eigen::Vector3f(1.0F, 0, 0), 0, 1},
                                         {Eigen::Vector3f(0, 2.0F, 0), 0, 2},
                                         {Eigen::Vector3f(150.0F, 0, 0), 0, 3},
                                         {Eigen::Vector3f(0, 0, 99.0F), 0, 4}};
  std::vector<uint16_t> rings;
  const auto out = deskewer.deskew(0, points, Eigen::Isometry3d::Identity(), DeskewImu{}, rings);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(rings, (std::vector<uint16_t>{2, 4}));
  EXPECT_TRUE(out[0].isApprox(Eigen::Vector3d(0, 2, 0)));
}

TEST(Deskewing, ASweepWithoutPointTimesOrWithDeskewingOffIsTakenAsItIs) {
  MovingSweep s(drive_and_turn(), 500);
  const Eigen::Isometry3d motion = pose_at(drive_and_turn(), kSpan);
  std::vector<uint16_t> rings;
  FrontendParams off;
  off.deskew = false;
  const auto as_is = Deskewer(off).deskew(0, s.points, motion, DeskewImu{}, rings);
  for (auto& p : s.points) p.time_offset = 0.0F;
  const auto timeless = Deskewer(FrontendParams{}).deskew(0, s.points, motion, DeskewImu{}, rings);
  ASSERT_EQ(as_is.size(), s.points.size());
  ASSERT_EQ(timeless.size(), s.points.size());
  for (size_t i = 0; i < s.points.size(); ++i) {
    EXPECT_EQ(as_is[i], s.points[i].p.cast<double>());
    EXPECT_EQ(timeless[i], s.points[i].p.cast<double>());
  }
  EXPECT_EQ(latest_point_time(s.points), 0.0F);
}

TEST(Deskewing, TheImusRotationReplacesConstantVelocitysWhereItCovers) {
  // A sensor turning at 2 rad/s on the spot, seen by the IMU; the motion given is none.
  geometry::Vector6d xi = geometry::Vector6d::Zero();
  xi(5) = 2.0 * kSpan;
  const MovingSweep s(xi, 1000);
  ImuBuffer imu;
  for (int64_t t = -50'000'000; t <= 200'000'000; t += 5'000'000)
    imu.add({t, Eigen::Vector3d(0, 0, 2.0), Eigen::Vector3d::Zero()}, 0);
  const Deskewer deskewer{FrontendParams{}};
  std::vector<uint16_t> rings;
  DeskewImu with_imu;
  with_imu.imu = &imu;
  const auto turned = deskewer.deskew(0, s.points, Eigen::Isometry3d::Identity(), with_imu, rings);
  EXPECT_LT(worst_error(turned, s.scene), 1e-4);
  // The gyro bias is the whole turn: nothing is moved.
  with_imu.gyro_bias = Eigen::Vector3d(0, 0, 2.0);
  const auto biased = deskewer.deskew(0, s.points, Eigen::Isometry3d::Identity(), with_imu, rings);
  for (size_t i = 0; i < biased.size(); ++i) EXPECT_LT((biased[i] - s.points[i].p.cast<double>()).norm(), 1e-5);
}

TEST(Deskewing, SelectsOnePointPerVoxelWithItsNormal) {
  // A sweep without rings of a flat ground 1.7 m below the sensor, every 10 cm.
  std::vector<ScanPoint> ground;
  for (int i = -150; i <= 150; ++i) {
    for (int j = -150; j <= 150; ++j)
      ground.push_back({Eigen::Vector3f(0.1F * static_cast<float>(i), 0.1F * static_cast<float>(j), -1.7F), 0, 0});
  }
  const FrontendParams p;  // normals on 0.2 m voxels, one point per 1 m voxel
  const Sweep sw = Deskewer(p).prepare(0, ground, Eigen::Isometry3d::Identity(), DeskewImu{});
  EXPECT_LT(sw.cloud.size(), ground.size() / 3) << "reduced to one point per normal voxel";
  EXPECT_GT(sw.points.size(), 500u);
  EXPECT_LE(sw.points.size(), 31u * 31u);
  ASSERT_EQ(sw.points.size(), sw.normals.size());
  for (const auto& n : sw.normals) EXPECT_GT(std::abs(n.z()), 0.99);
}

}  // namespace
}  // namespace cdc::frontend
