// The map core on simulated keyframes: clouds placed with their poses agree with the world,
// a pose update moves only the keyframes that moved, the OctoMap holds the walls as occupied and
// the space the rays crossed as free, and both files are written and read back.
#include "cdc/map/map_core.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"

#include <gtest/gtest.h>
#include <octomap/octomap.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <random>

namespace cdc::map {
namespace {

struct Scene {
  sim::World world;
  std::vector<Eigen::Isometry3d> poses;
  std::vector<std::vector<Eigen::Vector3f>> clouds;
  Scene() {
    std::vector<Eigen::Vector3d> path;
    for (int i = 0; i < 30; ++i) path.emplace_back(2.0 * i, 0, 1.73);
    sim::WorldOptions wo;
    wo.seed = 6;
    wo.spacing_m = 8;
    world = sim::World::generate({path}, wo);
    std::mt19937_64 rng(2);
    for (int k = 0; k < 4; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = path[static_cast<size_t>(5 + 5 * k)];
      poses.push_back(T);
      std::vector<Eigen::Vector3f> c;
      for (const auto& p : sim::sweep(
               world, sim::LidarModel::vlp16(), [&](double) { return T; }, rng))
        c.emplace_back(p.x, p.y, p.z);
      clouds.push_back(c);
    }
  }
};

// Distance from a world point to the nearest surface along the ray from `origin` (the point
// should lie on the first surface the ray meets).
double surface_error(const sim::World& w, const Eigen::Vector3d& origin, const Eigen::Vector3f& p) {
  const Eigen::Vector3d d = p.cast<double>() - origin;
  const auto hit = w.cast(origin, d.normalized(), d.norm() + 5.0);
  return hit ? std::abs(hit->range - d.norm()) : 1e9;
}

TEST(MapCore, PlacesCloudsWithTheirPosesAndMovesOnlyWhatMoved) {
  const Scene s;
  MapCore core(MapParams{});
  for (uint32_t k = 0; k < 4; ++k) core.add_keyframe(0, k, s.clouds[k]);
  EXPECT_EQ(core.placed_keyframes(), 0u) << "nothing is placed before its pose is known";
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;
  for (uint32_t k = 0; k < 4; ++k) poses.emplace_back(k, s.poses[k]);
  poses.emplace_back(99, Eigen::Isometry3d::Identity());  // a pose for a keyframe not received (yet)
  EXPECT_EQ(core.set_poses(0, poses), 4u);
  EXPECT_EQ(core.stats().unknown_keyframe_poses, 1u);
  const auto cloud = core.global_cloud();
  ASSERT_GT(cloud.size(), 5000u);
  size_t far = 0;
  for (size_t i = 0; i < cloud.size(); i += 7) {
    // Every placed point lies on a surface seen from one of the keyframes.
    double best = 1e9;
    for (const auto& T : s.poses) best = std::min(best, surface_error(s.world, T.translation(), cloud[i]));
    far += best > 0.3 ? 1 : 0;
  }
  EXPECT_LT(static_cast<double>(far), 0.02 * static_cast<double>(cloud.size() / 7));
  // Only the keyframe that moved is placed again; tiny changes are ignored.
  poses.pop_back();
  poses[1].second.translation().x() += 0.5;
  poses[2].second.translation().x() += 0.001;
  const uint64_t before = core.stats().placements;
  EXPECT_EQ(core.set_poses(0, poses), 1u);
  EXPECT_EQ(core.stats().placements, before + 1);
}

TEST(MapCore, OctoMapHasOccupiedSurfacesAndFreeSpaceAndFilesRoundTrip) {
  const Scene s;
  MapCore core(MapParams{});
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;
  for (uint32_t k = 0; k < 4; ++k) {
    core.add_keyframe(1, k, s.clouds[k]);
    poses.emplace_back(k, s.poses[k]);
  }
  core.set_poses(1, poses);
  const octomap::OcTree& tree = core.octree();
  // Rays along a beam from the first keyframe: free right after the sensor, stopped by the OctoMap
  // where the world's surface is.
  const Eigen::Vector3d o = s.poses[0].translation();
  size_t checked = 0, free_ok = 0, occ_ok = 0;
  for (int k = 0; k < 36; ++k) {
    const double el = -1.0 * M_PI / 180;  // along one of the VLP-16's beams
    const Eigen::Vector3d d(std::cos(el) * std::cos(k * M_PI / 18), std::cos(el) * std::sin(k * M_PI / 18),
                            std::sin(el));
    const auto hit = s.world.cast(o, d, 40.0);
    if (!hit || hit->range < 4.0) continue;
    ++checked;
    const Eigen::Vector3d near = o + d * 2.0;
    const auto* nf = tree.search(near.x(), near.y(), near.z());
    free_ok += (nf != nullptr && !tree.isNodeOccupied(nf)) ? 1u : 0u;
    // A ray cast through the OctoMap (unknown space passed) stops at the surface the world has.
    octomap::point3d end;
    const bool stopped =
        tree.castRay(octomap::point3d(static_cast<float>(o.x()), static_cast<float>(o.y()), static_cast<float>(o.z())),
                     octomap::point3d(static_cast<float>(d.x()), static_cast<float>(d.y()), static_cast<float>(d.z())),
                     end, true, 45.0);
    const double range = Eigen::Vector3d(end.x() - o.x(), end.y() - o.y(), end.z() - o.z()).norm();
    occ_ok += (stopped && std::abs(range - hit->range) < 0.5) ? 1u : 0u;
  }
  ASSERT_GT(checked, 10u);
  EXPECT_GE(free_ok, checked * 9 / 10);
  EXPECT_GE(occ_ok, checked * 7 / 10);
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("cdc_map_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  core.write_pcd((dir / "map.pcd").string());
  core.write_octomap((dir / "map.bt").string());
  octomap::OcTree back(0.1);
  ASSERT_TRUE(back.readBinary((dir / "map.bt").string()));
  EXPECT_EQ(back.size(), tree.size());
  std::ifstream pcd(dir / "map.pcd", std::ios::binary);
  std::string line;
  size_t points = 0, header = 0;
  while (std::getline(pcd, line)) {
    header += line.size() + 1;
    if (line.rfind("POINTS ", 0) == 0) points = std::stoul(line.substr(7));
    if (line == "DATA binary") break;
  }
  EXPECT_EQ(points, core.global_cloud().size());
  EXPECT_EQ(std::filesystem::file_size(dir / "map.pcd"), header + points * 12);
  EXPECT_THROW(core.write_pcd((dir / "missing" / "x.pcd").string()), std::runtime_error);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace cdc::map
