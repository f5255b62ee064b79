// Smooth continuous-time trajectories for simulation: a uniform cubic B-spline in position and a
// cumulative cubic B-spline on SO(3), built from uniformly sampled poses (e.g. KITTI ground truth
// at 10 Hz). The spline itself is the ground truth every sensor is simulated from.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace cdc::sim {

class SplineTrajectory {
 public:
  SplineTrajectory() = default;
  // Control poses sampled every dt_s seconds from t0_s on (at least 4).
  SplineTrajectory(std::vector<Eigen::Isometry3d> controls, double t0_s, double dt_s);

  double start() const noexcept { return t0_ + dt_; }  // valid time span
  double end() const noexcept { return t0_ + dt_ * static_cast<double>(controls_.size() - 2); }

  Eigen::Isometry3d pose(double t) const;            // T_world_body
  Eigen::Vector3d velocity(double t) const;          // world frame [m/s]
  Eigen::Vector3d acceleration(double t) const;      // world frame [m/s^2]
  Eigen::Vector3d angular_velocity(double t) const;  // body frame [rad/s]

 private:
  size_t segment(double t, double& u) const;
  std::vector<Eigen::Isometry3d> controls_;
  std::vector<Eigen::Vector3d> omega_;  // Log(R_{i-1}^T R_i)
  double t0_ = 0, dt_ = 0.1;
};

struct ImuSample {
  double t = 0;
  Eigen::Vector3d accel;  // specific force in the IMU frame [m/s^2]
  Eigen::Vector3d gyro;   // [rad/s]
};

struct ImuNoise {                   // continuous-time densities (consumer MEMS defaults)
  double accel_noise = 2.0e-3;      // [m/s^2/sqrt(Hz)]
  double gyro_noise = 1.7e-4;       // [rad/s/sqrt(Hz)]
  double accel_bias_walk = 3.0e-4;  // [m/s^3/sqrt(Hz)]
  double gyro_bias_walk = 2.0e-5;   // [rad/s^2/sqrt(Hz)]
  static ImuNoise none() { return ImuNoise{0, 0, 0, 0}; }
};

inline const Eigen::Vector3d kGravity(0, 0, -9.80665);  // world frame, z up [m/s^2]

// IMU samples at rate_hz over [t0, t1] for a body moving along `trajectory`, the IMU mounted at
// T_body_imu; noise and bias random walk from `noise` (seeded).
std::vector<ImuSample> simulate_imu(const SplineTrajectory& trajectory, const Eigen::Isometry3d& T_body_imu, double t0,
                                    double t1, double rate_hz, const ImuNoise& noise, uint64_t seed);

}  // namespace cdc::sim
