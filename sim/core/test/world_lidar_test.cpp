#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cdc::sim {
namespace {

// A closed room: walls at x, y = +-10 m, floor at z = 0, ceiling at z = 6 m.
World room() {
  Ground g;  // z = 0
  std::vector<Box> walls = {
      {Eigen::Vector3d(10.5, 0, 3), Eigen::Vector3d(0.5, 11, 3.5), 0, 0.5f},
      {Eigen::Vector3d(-10.5, 0, 3), Eigen::Vector3d(0.5, 11, 3.5), 0, 0.5f},
      {Eigen::Vector3d(0, 10.5, 3), Eigen::Vector3d(11, 0.5, 3.5), 0, 0.5f},
      {Eigen::Vector3d(0, -10.5, 3), Eigen::Vector3d(11, 0.5, 3.5), 0, 0.5f},
      {Eigen::Vector3d(0, 0, 6.5), Eigen::Vector3d(11, 11, 0.5), 0, 0.5f},
  };
  return World(g, walls, {});
}

Eigen::Isometry3d at(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

LidarModel exact(LidarModel m) {
  m.range_sigma_m = 0;
  m.dropout = 0;
  return m;
}

// A world of flat ground at height z0 [m] and nothing else.
World flat_ground(double z0) {
  Ground g;
  g.z0 = z0;
  return World(g, {}, {});
}

// A sweep of a sensor standing still at the origin.
std::vector<LidarReturn> sweep_at_origin(const World& w, const LidarModel& m, std::mt19937_64& rng) {
  return sweep(
      w, m, [](double) { return at(0, 0, 0); }, rng);
}

double distance(const LidarReturn& p) { return std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z); }

// A sweep from the origin of flat ground 2 m below: every point of ring 0 goes to check0, every point
// of ring 1 to check1, and each of the two rings has one point per column.
template <typename Check0, typename Check1>
void check_rings_on_ground(const LidarModel& m, std::mt19937_64& rng, Check0 check0, Check1 check1) {
  int n0 = 0, n1 = 0;
  for (const LidarReturn& p : sweep_at_origin(flat_ground(-2.0), m, rng)) {
    if (p.ring == 0) {
      check0(p);
      ++n0;
    } else if (p.ring == 1) {
      check1(p);
      ++n1;
    }
  }
  EXPECT_EQ(n0, m.columns);
  EXPECT_EQ(n1, m.columns);
}

TEST(World, RayAgainstTheGroundPlaneGivesTheAnalyticRange) {
  const World w = flat_ground(-2.0);
  const Eigen::Vector3d d = Eigen::Vector3d(std::cos(0.3), 0, -std::sin(0.3));
  const auto hit = w.cast(Eigen::Vector3d::Zero(), d, 100);
  ASSERT_TRUE(hit);
  EXPECT_NEAR(hit->range, 2.0 / std::sin(0.3), 1e-12);
  EXPECT_NEAR(hit->normal.z(), 1.0, 1e-12);
  EXPECT_FALSE(w.cast(Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ(), 100));  // up: nothing
}

TEST(World, SlopedGroundAndBoxesAndCylinders) {
  Ground g;
  g.gx = 0.1;  // z = 0.1 x
  Box b{Eigen::Vector3d(20, 0, 0), Eigen::Vector3d(1, 1, 5), M_PI / 4, 0.7f};
  Cylinder c{0, 15, 0.5, -10, 10, 0.9f};
  const World w(g, {b}, {c});
  const Eigen::Vector3d o(0, 0, 1);
  // Along +x at z = 1 the sloped ground (z = 0.1 x) is met at x = 10 before the box at x ~ 18.6.
  auto h = w.cast(o, Eigen::Vector3d::UnitX(), 100);
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->range, 10.0, 1e-9);
  // Horizontally along +y: the pole's surface at y = 14.5.
  h = w.cast(Eigen::Vector3d(0, 0, 5), Eigen::Vector3d::UnitY(), 100);
  ASSERT_TRUE(h);
  EXPECT_NEAR(h->range, 14.5, 1e-9);
  EXPECT_FLOAT_EQ(h->reflectance, 0.9f);
  // A ray at the rotated box's corner direction hits its vertex at 20 - sqrt(2).
  h = w.cast(Eigen::Vector3d(0, 0, 2.5), Eigen::Vector3d(1, 0, 0.1).normalized(), 100);
  ASSERT_TRUE(h);
}

TEST(Lidar, StaticSensorInARoomSeesEveryWallExactly) {
  const World w = room();
  const LidarModel m = exact(LidarModel::vlp16());
  std::mt19937_64 rng(1);
  const auto pts = sweep(
      w, m, [](double) { return at(0, 0, 1.7); }, rng);
  EXPECT_EQ(pts.size(), m.rays());  // closed room: every ray returns
  for (const auto& p : pts) {
    const Eigen::Vector3d q(p.x, p.y, p.z + 1.7);  // world coordinates
    const bool on_surface = std::abs(std::abs(q.x()) - 10) < 1e-4 || std::abs(std::abs(q.y()) - 10) < 1e-4 ||
                            std::abs(q.z()) < 1e-4 || std::abs(q.z() - 6) < 1e-4;
    ASSERT_TRUE(on_surface) << q.transpose();
    ASSERT_LE(std::max(std::abs(q.x()), std::abs(q.y())), 10 + 1e-4);
  }
  EXPECT_EQ(pts.front().ring, 0);
  EXPECT_FLOAT_EQ(pts.front().time_offset, 0.0f);
  EXPECT_NEAR(pts.back().time_offset, 0.1 * 1799 / 1800, 1e-6);
}

TEST(Lidar, RangeNoiseAndDropoutsHaveTheConfiguredSize) {
  const World w = room();
  LidarModel m = LidarModel::vlp16();
  m.range_sigma_m = 0.05;
  m.dropout = 0.1;
  std::mt19937_64 rng(2);
  const auto pts = sweep(
      w, m, [](double) { return at(0, 0, 1.7); }, rng);
  EXPECT_NEAR(static_cast<double>(pts.size()) / static_cast<double>(m.rays()), 0.9, 0.01);
  // Points on the +x wall: the range error along the ray is x / (cos el cos az) - true range.
  double sum = 0, sq = 0;
  int n = 0;
  for (const auto& p : pts) {
    const Eigen::Vector3d d(p.x, p.y, p.z);
    const Eigen::Vector3d u = d.normalized();
    if (u.x() > 0.9 && std::abs(u.z()) < 0.1) {  // beams within +-5.7 deg reach the wall, not floor or ceiling
      const double truth = 10.0 / u.x();
      const double err = d.norm() - truth;
      sum += err;
      sq += err * err;
      ++n;
    }
  }
  ASSERT_GT(n, 1000);
  EXPECT_NEAR(sum / n, 0.0, 0.01);
  EXPECT_NEAR(std::sqrt(sq / n), 0.05, 0.005);
}

TEST(Lidar, ElevationCalibrationErrorPutsPointsAlongTheNominalBeam) {
  // Flat ground 2 m below the sensor. Beam 0 of the VLP-16 (nominal -15 deg) really fires at
  // -15.5 deg: it meets the ground at 2 / sin(15.5 deg), and that range is reported along -15 deg.
  LidarModel m = exact(LidarModel::vlp16());
  m.elevation_error_deg.assign(m.elevations_deg.size(), 0.0);
  m.elevation_error_deg[0] = -0.5;
  std::mt19937_64 rng(1);
  const double range = 2.0 / std::sin(15.5 * M_PI / 180), z = -range * std::sin(15.0 * M_PI / 180);
  check_rings_on_ground(
      m, rng,
      [&](const LidarReturn& p) {
        EXPECT_NEAR(distance(p), range, 1e-3);
        EXPECT_NEAR(p.z, z, 1e-3);  // 1.93 m: the ground looks like a cone, not a plane
      },
      [](const LidarReturn& p) { EXPECT_NEAR(p.z, -2.0, 1e-3); });  // an exact beam still sees the plane
  m.elevation_error_deg.resize(3);
  EXPECT_THROW(sweep_at_origin(flat_ground(-2.0), m, rng), std::invalid_argument);
}

TEST(Lidar, AzimuthCalibrationErrorTurnsTheBeamButNotItsReportedDirection) {
  // A wall whose face is the plane y = 5. Ring 8 of the VLP-16 (+1 deg) really fires 0.5 deg ahead of
  // each column's azimuth; its range is reported along the nominal azimuth, so the wall's points bend
  // away from the plane: y = 5 sin(az) / sin(az + 0.5 deg). Ring 9 is exact and sees the plane.
  Ground g;
  g.z0 = -50.0;
  const World w(g, {{Eigen::Vector3d(0, 5.5, 0), Eigen::Vector3d(200, 0.5, 40), 0, 0.5f}}, {});
  LidarModel m = exact(LidarModel::vlp16());
  m.azimuth_error_deg.assign(m.elevations_deg.size(), 0.0);
  m.azimuth_error_deg[8] = 0.5;
  std::mt19937_64 rng(1);
  const auto pts = sweep_at_origin(w, m, rng);
  const double d = 0.5 * M_PI / 180;
  int n8 = 0, n9 = 0;
  double max_bend = 0;
  for (const auto& p : pts) {
    const double az = std::atan2(p.y, p.x);
    if (az < 0.3 || az > M_PI - 0.3) continue;  // far along the wall the ranges grow without bound
    if (p.ring == 8) {
      const double expected = 5.0 * std::sin(az) / std::sin(az + d);
      EXPECT_NEAR(p.y, expected, 1e-3) << "az " << az;
      max_bend = std::max(max_bend, std::abs(p.y - 5.0));
      ++n8;
    } else if (p.ring == 9) {
      EXPECT_NEAR(p.y, 5.0, 1e-3);
      ++n9;
    }
  }
  EXPECT_GT(n8, 500);
  EXPECT_GT(n9, 500);
  EXPECT_GT(max_bend, 0.1);  // near az = 0.3 rad the point sits about 0.14 m off the wall
  m.azimuth_error_deg.resize(3);
  EXPECT_THROW(sweep_at_origin(w, m, rng), std::invalid_argument);
}

TEST(Lidar, RangeOffsetLengthensEveryReturnOfItsBeam) {
  // Flat ground 2 m below: ring 0 (-15 deg) reports 5 cm too far, ring 1 is exact.
  LidarModel m = exact(LidarModel::vlp16());
  m.range_offset_m.assign(m.elevations_deg.size(), 0.0);
  m.range_offset_m[0] = 0.05;
  std::mt19937_64 rng(1);
  const double r0 = 2.0 / std::sin(15.0 * M_PI / 180) + 0.05, r1 = 2.0 / std::sin(13.0 * M_PI / 180);
  check_rings_on_ground(
      m, rng, [&](const LidarReturn& p) { EXPECT_NEAR(distance(p), r0, 1e-3); },
      [&](const LidarReturn& p) { EXPECT_NEAR(distance(p), r1, 1e-3); });
  m.range_offset_m.resize(17);
  EXPECT_THROW(sweep_at_origin(flat_ground(-2.0), m, rng), std::invalid_argument);
}

TEST(Lidar, AMovingSensorsSweepIsDistortedByExactlyTheMotion) {
  const World w = room();
  const LidarModel m = exact(LidarModel::vlp16());
  const double v = 8.0;  // [m/s] along +x
  std::mt19937_64 rng(3);
  const auto pts = sweep(
      w, m, [&](double t) { return at(-2.0 + v * t, 0, 1.7); }, rng);
  // First and last column look almost the same way (+x wall), 0.1 s apart: each range is the wall
  // distance at its own instant, so the sweep does not close on itself.
  const LidarReturn* first = nullptr;
  const LidarReturn* last = nullptr;
  for (const auto& p : pts) {
    if (p.ring == 7) {
      if (first == nullptr) first = &p;
      last = &p;
    }
  }
  ASSERT_TRUE(first && last);
  auto expected = [&](const LidarReturn& p) {
    const Eigen::Vector3d u = Eigen::Vector3d(p.x, p.y, p.z).normalized();
    const double x_sensor = -2.0 + v * static_cast<double>(p.time_offset);
    return (10.0 - x_sensor) / u.x();
  };
  const double r_first = Eigen::Vector3d(first->x, first->y, first->z).norm();
  const double r_last = Eigen::Vector3d(last->x, last->y, last->z).norm();
  EXPECT_NEAR(r_first, expected(*first), 1e-5);
  EXPECT_NEAR(r_last, expected(*last), 1e-5);
  EXPECT_NEAR(r_first - r_last, v * static_cast<double>(last->time_offset) * 1.0, 0.01);  // ~0.8 m of motion
  EXPECT_GT(r_first - r_last, 0.75);
}

TEST(World, GeneratedCityKeepsClearOfThePathsAndIsDeterministic) {
  std::vector<Eigen::Vector3d> path;
  for (int i = 0; i < 200; ++i) {
    path.emplace_back(2.0 * i, 20 * std::sin(0.01 * i), 1.7);
  }
  WorldOptions o;
  o.seed = 42;
  const World a = World::generate({path}, o);
  const World b = World::generate({path}, o);
  ASSERT_GT(a.boxes().size(), 20u);
  ASSERT_EQ(a.boxes().size(), b.boxes().size());
  for (size_t i = 0; i < a.boxes().size(); ++i) {
    EXPECT_EQ(a.boxes()[i].center, b.boxes()[i].center);
  }
  // Nothing within the clearance of the path: horizontal rays from every path point run free for 2.9 m.
  for (const auto& p : path) {
    for (int k = 0; k < 16; ++k) {
      const double az = 2 * M_PI * k / 16;
      const Eigen::Vector3d d(std::cos(az), std::sin(az), 0);
      const Eigen::Vector3d o3(p.x(), p.y(), a.ground_height(p.x(), p.y()) + 1.0);
      const auto hit = a.cast(o3, d, 2.9);
      EXPECT_FALSE(hit) << "something within the clearance at " << p.transpose();
    }
  }
  WorldOptions other = o;
  other.seed = 43;
  EXPECT_NE(World::generate({path}, other).boxes().front().center, a.boxes().front().center);
}

TEST(World, TerrainFollowsTheElevationOfHillyPaths) {
  // A road that climbs 30 m over 600 m, then a second one 20 m lower: the sensor must stay its
  // mounting height above the ground everywhere (a single plane cannot do this).
  std::vector<Eigen::Vector3d> climb, low;
  for (int i = 0; i < 300; ++i) {
    climb.emplace_back(2.0 * i, 0.0, 1.73 + 0.05 * 2.0 * i);
    low.emplace_back(2.0 * i, 200.0, 1.73 - 20.0);
  }
  WorldOptions o;
  o.seed = 7;
  const World w = World::generate({climb, low}, o);
  ASSERT_FALSE(w.terrain().empty());
  for (const auto* path : {&climb, &low}) {
    for (size_t k = 0; k < path->size(); k += 7) {
      const Eigen::Vector3d& p = (*path)[k];
      const auto down = w.cast(p, Eigen::Vector3d(0, 0, -1), 50.0);
      ASSERT_TRUE(down) << "no ground under " << p.transpose();
      EXPECT_NEAR(down->range, 1.73, 0.15) << "at " << p.transpose();
      EXPECT_GT(down->normal.z(), 0.9);
    }
  }
  // The surface is continuous: heights along a line crossing cell borders change smoothly.
  double prev = w.ground_height(-50.0, 100.0);
  for (double x = -50; x < 650; x += 0.5) {
    const double z = w.ground_height(x, 100.0);
    EXPECT_LT(std::abs(z - prev), 0.5) << "step at x = " << x;
    prev = z;
  }
  // A horizontal ray at sensor height on the climbing road meets the slope ahead well beyond 10 m.
  const auto ahead = w.cast(climb[10], Eigen::Vector3d(1, 0, 0), 200.0);
  if (ahead) {
    EXPECT_GT(ahead->range, 10.0);
  }
}

TEST(World, PassesAtDifferentHeightsOverOnePlaceNeverBuryASensor) {
  // A road, and a second pass along the same line 3.1 m lower (KITTI 09's ground truth ends 3.1 m
  // below its start at the same place). A mean of the two would put the ground 0.2 m under the
  // lower pass's sensor; it must instead keep its mounting height, and the higher pass drives above.
  std::vector<Eigen::Vector3d> upper, lower;
  for (int i = 0; i < 100; ++i) {
    upper.emplace_back(1.0 * i, 0.0, 1.73);
    lower.emplace_back(1.0 * i + 0.3, 0.4, 1.73 - 3.1);
  }
  WorldOptions o;
  o.seed = 11;
  const World w = World::generate({upper, lower}, o);
  for (size_t k = 10; k < 90; k += 5) {
    const auto below_lower = w.cast(lower[k], Eigen::Vector3d(0, 0, -1), 50.0);
    ASSERT_TRUE(below_lower) << "no ground under " << lower[k].transpose();
    EXPECT_NEAR(below_lower->range, 1.73, 0.15) << "lower pass at " << lower[k].transpose();
    const auto below_upper = w.cast(upper[k], Eigen::Vector3d(0, 0, -1), 50.0);
    ASSERT_TRUE(below_upper) << "no ground under " << upper[k].transpose();
    EXPECT_GT(below_upper->range, 1.73 - 0.15) << "upper pass at " << upper[k].transpose();
  }
}

}  // namespace
}  // namespace cdc::sim
