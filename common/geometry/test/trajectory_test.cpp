#include "cdc/geometry/trajectory.hpp"
#include "cdc/geometry/se3.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

namespace cdc::geometry {
namespace {

namespace fs = std::filesystem;

class TrajectoryFiles : public test::TempDirTest {
 protected:
  TrajectoryFiles() : TempDirTest("traj_test") {}
  void write(const std::string& name, const std::string& text) const { std::ofstream(path(name)) << text; }
};

Trajectory sample_trajectory() {
  Trajectory t;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int i = 0; i < 50; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = from_rpy(u(rng), 0.5 * u(rng), 3 * u(rng));
    T.translation() = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 100.0;
    t.push_back({1'300'000'000'123'456'789LL + i * 100'000'000LL, T});
  }
  return t;
}

TEST_F(TrajectoryFiles, TumRoundTripKeepsStampsExactly) {
  const Trajectory t = sample_trajectory();
  write_tum(path("a.tum"), t);
  const Trajectory r = read_tum(path("a.tum"));
  ASSERT_EQ(r.size(), t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(r[i].stamp_ns, t[i].stamp_ns);
    EXPECT_LT((r[i].pose.matrix() - t[i].pose.matrix()).norm(), 1e-6);
  }
  EXPECT_EQ(detect_format(path("a.tum")), TrajectoryFormat::kTum);
}

TEST_F(TrajectoryFiles, KittiRoundTripWithPeriodStamps) {
  const Trajectory t = sample_trajectory();
  write_kitti(path("a.txt"), t);
  const Trajectory r = read_kitti(path("a.txt"), nullptr, 100'000'000);
  ASSERT_EQ(r.size(), t.size());
  for (size_t i = 0; i < t.size(); ++i) {
    EXPECT_EQ(r[i].stamp_ns, static_cast<int64_t>(i) * 100'000'000);
    EXPECT_LT((r[i].pose.matrix() - t[i].pose.matrix()).norm(), 1e-6);
  }
  EXPECT_EQ(detect_format(path("a.txt")), TrajectoryFormat::kKitti);
}

TEST_F(TrajectoryFiles, KittiWithTimesFile) {
  write("p.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n");
  write("t.txt", "0.000000e+00\n1.036400e-01\n");
  const auto times = read_times(path("t.txt"));
  ASSERT_EQ(times.size(), 2u);
  EXPECT_EQ(times[1], 103'640'000);
  const Trajectory r = read_kitti(path("p.txt"), &times);
  EXPECT_EQ(r[1].stamp_ns, 103'640'000);
  write("t3.txt", "0\n0.1\n0.2\n");
  const auto three = read_times(path("t3.txt"));
  EXPECT_THROW(read_kitti(path("p.txt"), &three), TrajectoryFileError);
}

TEST_F(TrajectoryFiles, BadFilesNameFileAndLine) {
  write("bad.tum", "# header\n0.0 1 2 3 0 0 0 1\n0.1 1 2 x 0 0 0 1\n");
  try {
    read_tum(path("bad.tum"));
    FAIL() << "expected an error";
  } catch (const TrajectoryFileError& e) {
    EXPECT_EQ(e.line(), 3u);
    EXPECT_NE(std::string(e.what()).find("bad.tum:3"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'x'"), std::string::npos) << e.what();
  }
  write("cols.tum", "0.0 1 2 3 0 0 0\n");
  EXPECT_THROW(read_tum(path("cols.tum")), TrajectoryFileError);
  write("norm.tum", "0.0 1 2 3 0 0 0 2\n");
  EXPECT_THROW(read_tum(path("norm.tum")), TrajectoryFileError);
  write("order.tum", "1.0 1 2 3 0 0 0 1\n0.5 1 2 3 0 0 0 1\n");
  EXPECT_THROW(read_tum(path("order.tum")), TrajectoryFileError);
  write("rot.txt", "2 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_THROW(read_kitti(path("rot.txt")), TrajectoryFileError);
  write("nan.txt", "1 0 0 nan 0 1 0 0 0 0 1 0\n");
  EXPECT_THROW(read_kitti(path("nan.txt")), TrajectoryFileError);
  EXPECT_THROW(read_tum(path("missing.tum")), TrajectoryFileError);
  write("five.txt", "1 2 3 4 5\n");
  EXPECT_THROW(detect_format(path("five.txt")), TrajectoryFileError);
}

TEST(Trajectory, ParseSeconds) {
  EXPECT_EQ(parse_seconds_ns("1305031102.175304"), 1305031102175304000LL);
  EXPECT_EQ(parse_seconds_ns("0.1"), 100'000'000);
  EXPECT_EQ(parse_seconds_ns("-0.5"), -500'000'000);
  EXPECT_EQ(parse_seconds_ns("1.036400e-01"), 103'640'000);
  EXPECT_EQ(parse_seconds_ns("12"), 12'000'000'000);
  EXPECT_FALSE(parse_seconds_ns("abc"));
  EXPECT_FALSE(parse_seconds_ns(""));
  EXPECT_FALSE(parse_seconds_ns("1.2.3"));
  // The int64 nanosecond range ends at 9223372036.854775807 s: the last whole second fits, with
  // any fraction; ten-digit stamps beyond are refused, not overflowed.
  EXPECT_EQ(parse_seconds_ns("9223372035.999999999"), 9'223'372'035'999'999'999LL);
  EXPECT_EQ(parse_seconds_ns("-9223372035.5"), -9'223'372'035'500'000'000LL);
  EXPECT_FALSE(parse_seconds_ns("9223372036"));
  EXPECT_FALSE(parse_seconds_ns("9999999999"));
  EXPECT_FALSE(parse_seconds_ns("-9999999999.1"));
}

TEST(Trajectory, InterpolateAt) {
  Trajectory t;
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.translation() = Eigen::Vector3d(10, 0, 0);
  b.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  t.push_back({1000, a});
  t.push_back({2000, b});
  const auto m = interpolate_at(t, 1250);
  ASSERT_TRUE(m);
  EXPECT_NEAR(m->translation().x(), 2.5, 1e-12);
  EXPECT_NEAR(rotation_angle(m->rotation()), 0.1, 1e-12);
  EXPECT_FALSE(interpolate_at(t, 999));
  EXPECT_FALSE(interpolate_at(t, 2001));
  EXPECT_LT((interpolate_at(t, 2000)->matrix() - b.matrix()).norm(), 1e-15);
}

TEST(Trajectory, AssociateNearestWithinTolerance) {
  Trajectory a, b;
  for (int i = 0; i < 10; ++i) {
    a.push_back({i * 100, Eigen::Isometry3d::Identity()});
  }
  for (int i = 0; i < 10; ++i) {
    b.push_back({i * 100 + 3, Eigen::Isometry3d::Identity()});
  }
  b[5].stamp_ns = 560;  // too far from 500 and 600 with max_dt 10
  const auto pairs = associate(a, b, 10);
  ASSERT_EQ(pairs.size(), 9u);
  for (auto [i, j] : pairs) {
    EXPECT_EQ(i, j);
    EXPECT_NE(i, 5u);
  }
}

TEST(Trajectory, PathLength) {
  Trajectory t;
  for (int i = 0; i < 5; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(3.0 * i, 4.0 * i, 0);
    t.push_back({i, T});
  }
  EXPECT_NEAR(path_length(t), 20.0, 1e-12);
}

}  // namespace
}  // namespace cdc::geometry
