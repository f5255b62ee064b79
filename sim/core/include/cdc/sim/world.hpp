// A procedural 3D world for ray casting: a ground (a plane, or a terrain height field that follows
// the trajectories' elevation), yawed boxes (buildings, walls, parked cars, tree crowns) and
// vertical cylinders (poles, trunks), with a uniform 2D grid for fast ray traversal. Generated
// deterministically from a seed around a set of trajectories.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <optional>
#include <vector>

namespace cdc::sim {

struct Box {
  Eigen::Vector3d center;
  Eigen::Vector3d half;  // half extents along the box's own axes [m]
  double yaw = 0;        // rotation about z [rad]
  float reflectance = 0.5f;
};

struct Cylinder {  // vertical
  double x = 0, y = 0, radius = 0.1, z0 = 0, z1 = 5;
  float reflectance = 0.5f;
};

struct Ground {  // z = z0 + gx x + gy y
  double z0 = 0, gx = 0, gy = 0;
  float reflectance = 0.3f;
  double height(double x, double y) const { return z0 + gx * x + gy * y; }
};

// A height field on a regular grid of vertices: origin at vertex (0, 0), nx x ny cells of `cell`
// metres, heights z[j * (nx + 1) + i]. Each cell is two triangles split along the (0,0)-(1,1)
// diagonal, so the surface is continuous.
struct Terrain {
  Eigen::Vector2d origin{0, 0};
  double cell = 10.0;
  int nx = 0, ny = 0;
  std::vector<double> z;
  bool empty() const noexcept { return nx == 0 || ny == 0; }
  double vertex(int i, int j) const {
    return z[static_cast<size_t>(j) * static_cast<size_t>(nx + 1) + static_cast<size_t>(i)];
  }
  // Height at (x, y), clamped to the grid's edge outside it.
  double height(double x, double y) const;
};

struct Hit {
  double range = 0;        // distance along the unit ray [m]
  Eigen::Vector3d normal;  // unit surface normal facing the ray
  float reflectance = 0;
};

struct WorldOptions {
  uint64_t seed = 1;
  double clearance_m = 3.0;       // no surface closer than this to a trajectory (horizontally)
  double spacing_m = 15.0;        // one placement attempt per side every this far along a path
  double cell_m = 10.0;           // ray-casting grid cell, also the terrain's cell
  double sensor_height_m = 1.73;  // the trajectories are sensor poses this high above the ground
  double terrain_margin_m = 150;  // terrain extends this far beyond every path point
};

class World {
 public:
  World() = default;
  World(Ground ground, std::vector<Box> boxes, std::vector<Cylinder> cylinders, double cell_m = 10.0);
  // A world on terrain: the ray-casting grid is the terrain's grid; no ground outside it.
  World(Terrain terrain, std::vector<Box> boxes, std::vector<Cylinder> cylinders);

  // Generates a city around the given paths (world xy positions, metres apart or closer).
  static World generate(const std::vector<std::vector<Eigen::Vector3d>>& paths, const WorldOptions& options);

  // Nearest surface hit along origin + t * dir (dir unit), t in (0, max_range].
  std::optional<Hit> cast(const Eigen::Vector3d& origin, const Eigen::Vector3d& dir, double max_range) const;

  const Ground& ground() const noexcept { return ground_; }  // the plane (unused with a terrain)
  const Terrain& terrain() const noexcept { return terrain_; }
  // Ground height at (x, y): the terrain's when there is one, else the plane's.
  double ground_height(double x, double y) const;
  const std::vector<Box>& boxes() const noexcept { return boxes_; }
  const std::vector<Cylinder>& cylinders() const noexcept { return cylinders_; }

 private:
  void build_grid();
  void index_objects();
  bool hit_terrain_cell(int i, int j, const Eigen::Vector3d& o, const Eigen::Vector3d& d, double& t,
                        Eigen::Vector3d& n) const;
  Ground ground_;
  Terrain terrain_;
  std::vector<Box> boxes_;
  std::vector<Cylinder> cylinders_;
  double cell_ = 10.0;
  Eigen::Vector2d min_{0, 0};
  int nx_ = 0, ny_ = 0;
  std::vector<std::vector<uint32_t>> cells_;  // object ids: boxes first, then cylinders (offset by boxes_.size())
};

}  // namespace cdc::sim
