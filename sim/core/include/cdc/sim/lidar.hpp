// A rotating multi-beam LiDAR. Columns fire in sequence over the sweep; each column is measured from
// the sensor pose at its own instant, so a moving sensor's sweep is really distorted. Points are in
// the sensor frame of their firing instant, with their time offset in the sweep.
#pragma once

#include "cdc/sim/world.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <vector>

namespace cdc::sim {

struct LidarModel {
  std::string name;
  std::vector<double> elevations_deg;  // beam elevations, ring 0 lowest
  int columns = 1800;                  // firings per revolution
  double rate_hz = 10.0;
  double min_range_m = 0.5;
  double max_range_m = 100.0;
  double range_sigma_m = 0.02;  // Gaussian range noise
  double dropout = 0.0;         // probability that a return is lost
  // Intrinsic calibration error: beam b really fires at elevations_deg[b] + elevation_error_deg[b],
  // while its points are reported along the nominal elevation (what a driver with a slightly wrong
  // calibration table does). Empty: a perfectly calibrated sensor.
  std::vector<double> elevation_error_deg;
  // The same for the azimuth: beam b fires azimuth_error_deg[b] ahead of the column's nominal azimuth
  // (a wrong rotational correction in the table). Empty: none.
  std::vector<double> azimuth_error_deg;
  // Per-beam distance offset: beam b reports its range range_offset_m[b] too long (a wrong distance
  // correction in the table; the VLP-16 is specified to +-3 cm). Empty: none.
  std::vector<double> range_offset_m;

  static LidarModel vlp16();  // 16 beams, -15..+15 deg, 0.2 deg at 10 Hz, 100 m
  static LidarModel hdl64();  // 64 beams, -24.9..+2 deg, ~0.17 deg at 10 Hz, 120 m
  double period_s() const { return 1.0 / rate_hz; }
  size_t rays() const { return elevations_deg.size() * static_cast<size_t>(columns); }
};

struct LidarReturn {
  float x, y, z;      // sensor frame at the firing instant [m]
  float intensity;    // reflectance x |cos(incidence)|, 0..1
  float time_offset;  // [s] since the start of the sweep
  uint16_t ring;
};

// pose_at(t) gives T_world_sensor at time t [s] after the start of the sweep.
std::vector<LidarReturn> sweep(const World& world, const LidarModel& model,
                               const std::function<Eigen::Isometry3d(double)>& pose_at, std::mt19937_64& rng);

}  // namespace cdc::sim
