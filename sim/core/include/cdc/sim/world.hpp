// A procedural 3D world for ray casting: a gently sloped ground, yawed boxes (buildings, walls,
// parked cars, tree crowns) and vertical cylinders (poles, trunks), with a uniform 2D grid for fast
// ray traversal. Generated deterministically from a seed around a set of trajectories.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <vector>

namespace cdc::sim {

struct Box {
  Eigen::Vector3d center;
  Eigen::Vector3d half;     // half extents along the box's own axes [m]
  double yaw = 0;           // rotation about z [rad]
  float reflectance = 0.5f;
};

struct Cylinder {            // vertical
  double x = 0, y = 0, radius = 0.1, z0 = 0, z1 = 5;
  float reflectance = 0.5f;
};

struct Ground {              // z = z0 + gx x + gy y
  double z0 = 0, gx = 0, gy = 0;
  float reflectance = 0.3f;
  double height(double x, double y) const { return z0 + gx * x + gy * y; }
};

struct Hit {
  double range = 0;          // distance along the unit ray [m]
  Eigen::Vector3d normal;    // unit surface normal facing the ray
  float reflectance = 0;
};

struct WorldOptions {
  uint64_t seed = 1;
  double clearance_m = 3.0;      // no surface closer than this to a trajectory (horizontally)
  double spacing_m = 15.0;       // one placement attempt per side every this far along a path
  double max_slope = 0.02;       // ground slope
  double cell_m = 10.0;          // ray-casting grid cell
};

class World {
 public:
  World() = default;
  World(Ground ground, std::vector<Box> boxes, std::vector<Cylinder> cylinders, double cell_m = 10.0);

  // Generates a city around the given paths (world xy positions, metres apart or closer).
  static World generate(const std::vector<std::vector<Eigen::Vector3d>>& paths, const WorldOptions& options);

  // Nearest surface hit along origin + t * dir (dir unit), t in (0, max_range].
  std::optional<Hit> cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range) const;

  const Ground& ground() const noexcept { return ground_; }
  const std::vector<Box>& boxes() const noexcept { return boxes_; }
  const std::vector<Cylinder>& cylinders() const noexcept { return cylinders_; }

 private:
  void build_grid();
  Ground ground_;
  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  double cell_ = 10.0;
  Eigen::Vector2d min_{0, 0};
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<uint32_t>> cells_;  // object ids: boxes first, then cylinders (offset by boxes_.size())
};

}  // namespace cdc::sim
