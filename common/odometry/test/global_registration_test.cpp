// The flat voxel index and the voxel map built on it (nearest neighbours as a brute-force search
// finds them, before and after the map slides), the fit test that tells a registration that found
// a sweep's place from one in a wrong minimum, and global registration (FPFH + RANSAC) recovering
// a sharp turn between two simulated sweeps without any guess.
#include "cdc/odometry/global_registration.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/normals.hpp"
#include "cdc/odometry/registration.hpp"
#include "cdc/odometry/voxel_index.hpp"
#include "cdc/odometry/voxel_map.hpp"
#include "sim_scene.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <limits>
#include <map>
#include <random>

namespace cdc::odometry {
namespace {

TEST(VoxelIndex, FindsWhatWasInsertedAndNothingElseAsItGrows) {
  VoxelIndex index;
  std::mt19937 rng(3);
  std::uniform_int_distribution<int32_t> coord(-2'000'000, 2'000'000);
  std::vector<Eigen::Vector3i> keys;
  for (uint32_t i = 0; i < 5000; ++i) {
    const Eigen::Vector3i k(coord(rng), coord(rng) % 7, coord(rng));
    const auto [value, added] = index.insert(k, i);
    if (added) {
      keys.push_back(k);
      EXPECT_EQ(value, i);
    }
    EXPECT_EQ(index.insert(k, 99'999).first, added ? i : value) << "an existing key keeps its payload";
  }
  EXPECT_EQ(index.size(), keys.size());
  for (size_t i = 0; i < keys.size(); ++i) EXPECT_NE(index.find(keys[i]), VoxelIndex::kNone);
  EXPECT_EQ(index.find(Eigen::Vector3i(2'100'000, 0, 0)), VoxelIndex::kNone);
  // Far or non-finite coordinates are clamped, never overflow the cast.
  EXPECT_EQ(voxel_coordinates(Eigen::Vector3d(1e300, -1e300, 0.5), 1.0), Eigen::Vector3i(1 << 30, -(1 << 30), 0));
  const Eigen::Vector3i nan_key =
      voxel_coordinates(Eigen::Vector3d(std::numeric_limits<double>::quiet_NaN(), 0, 0), 1.0);
  EXPECT_EQ(nan_key.x(), -(1 << 30));
}

TEST(VoxelMap, NearestIsTheBruteForceNearestBeforeAndAfterSliding) {
  VoxelMapParams p;
  p.voxel_m = 1.0;
  p.max_range_m = 20.0;
  p.max_points = 5;
  VoxelMap map(p);
  // The reference: every voxel's first max_points points, in a plain ordered map.
  std::map<std::array<int32_t, 3>, std::vector<Eigen::Vector3d>> reference;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-15.0, 15.0);
  auto add = [&](const Eigen::Vector3d& centre, int n) {
    std::vector<Eigen::Vector3d> pts;
    for (int i = 0; i < n; ++i) pts.push_back(centre + Eigen::Vector3d(u(rng), u(rng), 0.2 * u(rng)));
    map.add(pts);
    for (const auto& q : pts) {
      const Eigen::Vector3i k = voxel_coordinates(q, p.voxel_m);
      auto& v = reference[{k.x(), k.y(), k.z()}];
      if (v.size() < 5) v.push_back(q);
    }
  };
  auto slide = [&](const Eigen::Vector3d& c) {
    map.remove_far(c);
    std::erase_if(reference, [&](const auto& kv) { return (kv.second.front() - c).norm() > p.max_range_m; });
  };
  add(Eigen::Vector3d::Zero(), 3000);
  add(Eigen::Vector3d(30, 0, 0), 3000);
  slide(Eigen::Vector3d(30, 0, 0));  // drops the first cloud's voxels; the next cloud reuses their slots
  add(Eigen::Vector3d(40, 5, 0), 3000);
  add(Eigen::Vector3d(25, -5, 0), 3000);
  size_t held = 0;
  for (const auto& [k, v] : reference) held += v.size();
  EXPECT_EQ(map.voxels(), reference.size());
  EXPECT_EQ(map.points(), held);
  // Within one voxel's width the 27-voxel search is exact: the brute-force nearest of what the map holds.
  std::uniform_real_distribution<double> q(-20.0, 60.0);
  int found = 0;
  for (int i = 0; i < 2000; ++i) {
    const Eigen::Vector3d query(q(rng), 0.5 * q(rng) - 10.0, 0.1 * u(rng));
    double brute = 1.0;
    for (const auto& [k, v] : reference) {
      for (const auto& r : v) brute = std::min(brute, (r - query).squaredNorm());
    }
    Eigen::Vector3d out;
    double d2 = 0;
    const bool hit = map.nearest(query, out, d2, 1.0);
    ASSERT_EQ(hit, brute < 1.0) << "query " << query.transpose();
    if (!hit) continue;
    ++found;
    EXPECT_DOUBLE_EQ(d2, brute);
    EXPECT_DOUBLE_EQ((out - query).squaredNorm(), d2);
  }
  EXPECT_GT(found, 500);
}

// 40 m of path and an HDL-64 (the sweeps global registration gets in the front-end are dense).
struct Scene : test::SimScene {
  Scene() : test::SimScene(test::SceneOptions{}) {}
};

Eigen::Isometry3d pose(double x, double y, double yaw_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 1.73);
  T.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

TEST(GlobalRegistration, RecoversASharpTurnWithoutAGuessAndTheFitTellsTheMinima) {
  Scene s;
  const Eigen::Isometry3d A = pose(0, 0, 10), B = pose(0.8, 0.3, 65);  // 55 deg of turn, 0.85 m
  const std::vector<Eigen::Vector3d> a = s.scan(A), b = s.scan(B);
  const GlobalRegistrationParams gp;
  const FeatureCloud fa = make_feature_cloud(a, gp), fb = make_feature_cloud(b, gp);
  ASSERT_GT(fb.with_feature.size(), 200u);
  const GlobalRegistrationResult g = register_global(fb, fa, gp);
  ASSERT_TRUE(g.ok);
  const Eigen::Isometry3d truth = A.inverse() * B;
  const Eigen::Isometry3d e = truth.inverse() * g.T_target_source;
  std::printf("global: %d matches, %d inliers; error %.3f m %.2f deg\n", g.matches, g.inliers, e.translation().norm(),
              geometry::rotation_angle(e.rotation()) * 180 / M_PI);
  // Coarse (0.5 m voxels; measured 0.22 m, 0.26 deg), well inside the reach of the refinement below.
  EXPECT_LT(e.translation().norm(), 0.5);
  EXPECT_LT(geometry::rotation_angle(e.rotation()), 3.0 * M_PI / 180);
  // Deterministic: the same clouds give the same answer.
  const GlobalRegistrationResult again = register_global(fb, fa, gp);
  EXPECT_TRUE(again.T_target_source.isApprox(g.T_target_source, 0.0));

  // From the global answer scan-to-map registration finds the place; from the previous pose (no
  // motion) it settles in a wrong minimum, and the fit test tells them apart.
  VoxelMap map;
  std::vector<Eigen::Vector3d> world;
  for (const auto& p : voxel_filter(a, 0.5)) world.push_back(A * p);
  map.add(world);
  std::vector<Eigen::Vector3d> pts;
  for (const auto& p : voxel_filter(b, 1.0)) pts.push_back(p);
  const std::vector<Eigen::Vector3d> normals = knn_normals(pts, b, 10, 1.5);
  RegistrationSettings rp;
  rp.max_correspondence_m = 2.0;
  rp.kernel_m = 2.0 / 9;
  const RegistrationResult good = register_to_map(pts, normals, map, A * g.T_target_source, rp);
  const RegistrationResult stuck = register_to_map(pts, normals, map, A, rp);
  const Eigen::Isometry3d eg = B.inverse() * good.T_target_source, es = B.inverse() * stuck.T_target_source;
  EXPECT_LT(eg.translation().norm(), 0.05);
  EXPECT_GT(geometry::rotation_angle(es.rotation()), 10.0 * M_PI / 180) << "the wrong minimum this test needs";
  const FitQuality fg = evaluate_fit(pts, normals, map, good.T_target_source, 1.0, 0.1);
  const FitQuality fs = evaluate_fit(pts, normals, map, stuck.T_target_source, 1.0, 0.1);
  std::printf("fit: %.3f at the place, %.3f in the wrong minimum\n", fg.inlier_fraction, fs.inlier_fraction);
  EXPECT_GT(fg.inlier_fraction, 0.8);
  EXPECT_LT(fs.inlier_fraction, 0.75 * fg.inlier_fraction);
}

}  // namespace
}  // namespace cdc::odometry
