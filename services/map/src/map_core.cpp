#include "cdc/map/map_core.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <octomap/octomap.h>

#include <map>

#include <cmath>
#include <cstring>
#include <fstream>
#include <stdexcept>

namespace cdc::map {

MapCore::MapCore(const MapParams& params)
    : p_(params), tree_(std::make_unique<octomap::OcTree>(params.octree_resolution_m)) {}

MapCore::~MapCore() = default;

void MapCore::place(const Id& id, const Eigen::Isometry3d& T) {
  const auto c = clouds_.find(id);
  if (c == clouds_.end()) return;
  Placed& pl = placed_[id];
  pl.T_world = T;
  pl.world.clear();
  pl.world.reserve(c->second.size());
  const Eigen::Isometry3f Tf = T.cast<float>();
  for (const auto& p : c->second) pl.world.push_back(Tf * p);
  ++stats_.placements;
  tree_dirty_ = true;
}

void MapCore::add_keyframe(uint32_t robot, uint32_t id, std::vector<Eigen::Vector3f> cloud) {
  const Id key{robot, id};
  if (clouds_.count(key) != 0) return;
  clouds_[key] = std::move(cloud);
  ++stats_.keyframes;
  const auto p = poses_.find(key);
  if (p != poses_.end()) place(key, p->second);
}

size_t MapCore::set_poses(uint32_t robot, const std::vector<std::pair<uint32_t, Eigen::Isometry3d>>& poses) {
  ++stats_.pose_updates;
  size_t moved = 0;
  for (const auto& [id, T] : poses) {
    const Id key{robot, id};
    poses_[key] = T;
    if (clouds_.count(key) == 0) {
      ++stats_.unknown_keyframe_poses;
      continue;
    }
    const auto it = placed_.find(key);
    if (it != placed_.end()) {
      const Eigen::Isometry3d d = it->second.T_world.inverse() * T;
      if (d.translation().norm() <= p_.moved_m && geometry::rotation_angle(d.rotation()) <= p_.moved_rad) continue;
    }
    place(key, T);
    ++moved;
  }
  return moved;
}

std::vector<Eigen::Vector3f> MapCore::global_cloud() const {
  std::vector<Eigen::Vector3d> all;
  for (const auto& [id, pl] : placed_) {
    for (const auto& p : pl.world) all.push_back(p.cast<double>());
  }
  std::vector<Eigen::Vector3f> out;
  for (size_t i : odometry::voxel_filter_indices(all, p_.voxel_m)) out.push_back(all[i].cast<float>());
  return out;
}

const octomap::OcTree& MapCore::octree() {
  if (tree_dirty_) {
    tree_ = std::make_unique<octomap::OcTree>(p_.octree_resolution_m);
    // Ray casting dominates the cost (every ray crosses range / resolution cells) and consecutive
    // keyframes see the same free space: rays from keyframes ray_spacing_m apart, occupied cells
    // from all of them.
    std::map<uint32_t, Eigen::Vector3d> last_ray_origin;  // per robot
    for (const auto& [id, pl] : placed_) {
      const Eigen::Vector3d o = pl.T_world.translation();
      const uint32_t robot = id.first;
      auto last = last_ray_origin.find(robot);
      if (last == last_ray_origin.end() || (o - last->second).norm() >= p_.ray_spacing_m) {
        octomap::Pointcloud cloud;
        cloud.reserve(pl.world.size());
        for (const auto& p : pl.world) cloud.push_back(p.x(), p.y(), p.z());
        tree_->insertPointCloud(
            cloud, octomap::point3d(static_cast<float>(o.x()), static_cast<float>(o.y()), static_cast<float>(o.z())),
            p_.max_range_m, false, true);
        last_ray_origin[robot] = o;
      } else {
        for (const auto& p : pl.world) {
          if ((p.cast<double>() - o).norm() <= p_.max_range_m) tree_->updateNode(p.x(), p.y(), p.z(), true, true);
        }
      }
    }
    tree_->updateInnerOccupancy();
    tree_dirty_ = false;
    ++stats_.octree_rebuilds;
  }
  return *tree_;
}

void MapCore::write_pcd(const std::string& path) const {
  const std::vector<Eigen::Vector3f> pts = global_cloud();
  std::ofstream out(path, std::ios::binary);
  if (!out) throw std::runtime_error(path + ": cannot write");
  out << "# .PCD v0.7 - cdc-map global cloud\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
      << "WIDTH " << pts.size() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " << pts.size() << "\nDATA binary\n";
  for (const auto& p : pts) out.write(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
  if (!out) throw std::runtime_error(path + ": write failed");
}

void MapCore::write_octomap(const std::string& path) {
  if (!octree().writeBinaryConst(path)) throw std::runtime_error(path + ": cannot write the OctoMap");
}

}  // namespace cdc::map
