// The map service's synchronous core: every robot's keyframe clouds placed with the latest
// optimised poses into a global point cloud (voxel-filtered) and an OctoMap. When poses change,
// only the keyframes that moved are transformed again; the OctoMap, which cannot take points back,
// is rebuilt from the placed clouds when it is asked for after a change.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace octomap {
class OcTree;
}

namespace cdc::map {

struct MapParams {
  double voxel_m = 0.2;  // global cloud voxel filter
  double octree_resolution_m = 0.4;
  double max_range_m = 40.0;                 // rays longer than this are not inserted into the OctoMap
  double ray_spacing_m = 15.0;               // free space is ray-cast only from keyframes this far apart (per robot,
                                             // in order); every other keyframe adds its points as occupied only
  double moved_m = 0.02, moved_rad = 0.002;  // a keyframe is placed again when its pose moved more
};

struct MapStats {
  uint64_t keyframes = 0, placements = 0, pose_updates = 0, octree_rebuilds = 0, unknown_keyframe_poses = 0;
};

class MapCore {
 public:
  explicit MapCore(const MapParams& params);
  ~MapCore();

  // A keyframe's cloud (keyframe frame); placed once its world pose is known.
  void add_keyframe(uint32_t robot, uint32_t id, std::vector<Eigen::Vector3f> cloud);
  // Latest optimised world poses of a robot's keyframes. Returns how many keyframes were placed again.
  size_t set_poses(uint32_t robot, const std::vector<std::pair<uint32_t, Eigen::Isometry3d>>& T_world_keyframe);

  // Every placed keyframe's points, one per voxel.
  std::vector<Eigen::Vector3f> global_cloud() const;
  // The OctoMap of the placed keyframes (rebuilt first if anything moved since).
  const octomap::OcTree& octree();

  // Writers: binary PCD (x y z float32) and OctoMap binary (.bt). Throw std::runtime_error naming the path.
  void write_pcd(const std::string& path) const;
  void write_octomap(const std::string& path);

  size_t placed_keyframes() const noexcept { return placed_.size(); }
  const MapStats& stats() const noexcept { return stats_; }

 private:
  using Id = std::pair<uint32_t, uint32_t>;
  struct Placed {
    Eigen::Isometry3d T_world;
    std::vector<Eigen::Vector3f> world;  // the cloud in the world frame
  };
  void place(const Id& id, const Eigen::Isometry3d& T);

  MapParams p_;
  std::map<Id, std::vector<Eigen::Vector3f>> clouds_;  // keyframe frame
  std::map<Id, Eigen::Isometry3d> poses_;              // latest known, placed or not
  std::map<Id, Placed> placed_;
  std::unique_ptr<octomap::OcTree> tree_;
  bool tree_dirty_ = true;
  MapStats stats_;
};

}  // namespace cdc::map
