// Deskewing: a sweep made ready for registration. Its points are cropped to the range limits and
// moved into the sensor frame at the sweep's start along the motion over the sweep (constant
// velocity), or along the IMU's motion where the samples cover: its rotation, and its translation
// too when the IMU's state at the start is given (FrontendParams::imu_deskew). A sweep whose points
// all carry time 0 has no per-point times and is taken as it is. The points registered are then
// one per voxel_m voxel with their normals (on the range image when the sweep has rings, else from
// nearest neighbours).
#pragma once

#include "cdc/frontend/frontend_types.hpp"
#include "cdc/frontend/imu_buffer.hpp"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <vector>

namespace cdc::frontend {

// A sweep as it arrived.
struct SweepIn {
  int64_t stamp_ns = 0;
  const std::vector<ScanPoint>* points = nullptr;
  float t_max = 0;  // latest point time [s]; 0: the sweep has no per-point times
  double dt = 0.1;  // since the previous sweep [s]
};

// The latest point time of a sweep [s] (0: it has no per-point times).
float latest_point_time(const std::vector<ScanPoint>& points);

// A sweep made ready for registration: deskewed and cropped (sensor frame), and the points
// registered with their normals.
struct Sweep {
  std::vector<Eigen::Vector3d> cloud, points, normals;
};

// What deskewing takes from the IMU: the samples (none: constant velocity throughout), the biases
// and, for the IMU's whole motion, its state at the sweep's start.
struct DeskewImu {
  const ImuBuffer* imu = nullptr;
  Eigen::Vector3d gyro_bias = Eigen::Vector3d::Zero(), accel_bias = Eigen::Vector3d::Zero();
  const ImuStart* start = nullptr;
};

class Deskewer {
 public:
  explicit Deskewer(const FrontendParams& params);

  // The motion over a sweep's span t_max from the motion D over dt (constant velocity).
  static Eigen::Isometry3d motion_over(const Eigen::Isometry3d& D, float t_max, double dt);
  // The sweep cropped and deskewed along `sweep_motion` (the motion over its span), in the sensor
  // frame at its start; `rings` gets the ring of each point kept.
  std::vector<Eigen::Vector3d> deskew(int64_t stamp_ns, const std::vector<ScanPoint>& points,
                                      const Eigen::Isometry3d& sweep_motion, const DeskewImu& imu,
                                      std::vector<uint16_t>& rings) const;
  // Deskewed, then the points registered selected with their normals.
  Sweep prepare(int64_t stamp_ns, const std::vector<ScanPoint>& points, const Eigen::Isometry3d& sweep_motion,
                const DeskewImu& imu) const;

 private:
  static constexpr int kSlots = 64;  // instants the motion over a sweep is sampled at
  using Slots = std::array<Eigen::Isometry3d, kSlots + 1>;
  // The sensor's pose at kSlots + 1 instants over [0, span] relative to the sweep's start.
  Slots motion_slots(int64_t stamp_ns, double span, const Eigen::Isometry3d& sweep_motion, const DeskewImu& imu) const;
  bool in_range(const Eigen::Vector3d& p) const;
  Sweep select_on_rings(std::vector<Eigen::Vector3d> cloud, const std::vector<uint16_t>& rings) const;
  Sweep select_by_neighbours(std::vector<Eigen::Vector3d> cloud) const;

  FrontendParams p_;
};

}  // namespace cdc::frontend
