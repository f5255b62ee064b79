// The IMU samples the front-end keeps, and what deskewing and prediction take from them: the
// increments from a sweep's start to instants within it, the preintegration between two sweeps, and
// the LiDAR's rotation between two instants.
#pragma once

#include "cdc/frontend/frontend_types.hpp"
#include "cdc/odometry/imu_preintegration.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <vector>

namespace cdc::frontend {

// The IMU's increments (odometry::ImuDelta: in the IMU frame at `from`, gravity excluded) from
// `from` to each instant of `to` (ascending), in one pass over the bias-corrected samples (time
// order, sample-and-hold); none where the samples do not cover.
std::vector<std::optional<odometry::ImuDelta>> integrate_imu(const std::deque<ImuIn>& imu, int64_t from_ns,
                                                             const std::vector<int64_t>& to_ns,
                                                             const Eigen::Vector3d& gyro_bias,
                                                             const Eigen::Vector3d& accel_bias);
// The IMU's velocity and gravity at the start of an increment, in its body frame there.
struct ImuStart {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero(), gravity = Eigen::Vector3d::Zero();
};
// The LiDAR's pose at the end of `inc` relative to its pose at the start: rotation and translation
// when the start is known, else the rotation alone (no translation).
Eigen::Isometry3d lidar_motion(const odometry::ImuDelta& inc, const Eigen::Isometry3d& T_lidar_imu,
                               const ImuStart* start);

// The samples in time order, from half a second before the latest sweep on (what later sweeps can
// still need).
class ImuBuffer {
 public:
  // Keeps a sample newer than the last one (false: older or as old, dropped) and forgets those that
  // `latest_sweep_ns` no longer needs.
  bool add(const ImuIn& sample, int64_t latest_sweep_ns);
  void clear() { samples_.clear(); }
  bool empty() const noexcept { return samples_.empty(); }
  const std::deque<ImuIn>& samples() const noexcept { return samples_; }

  // integrate_imu over the samples kept.
  std::vector<std::optional<odometry::ImuDelta>> increments(int64_t from_ns, const std::vector<int64_t>& to_ns,
                                                            const Eigen::Vector3d& gyro_bias,
                                                            const Eigen::Vector3d& accel_bias) const {
    return integrate_imu(samples_, from_ns, to_ns, gyro_bias, accel_bias);
  }
  // The preintegration over [from, to] at the given biases; none where the samples do not cover.
  std::unique_ptr<odometry::ImuPreintegration> preintegrate(int64_t from_ns, int64_t to_ns,
                                                            const Eigen::Vector3d& gyro_bias,
                                                            const Eigen::Vector3d& accel_bias,
                                                            const odometry::ImuNoiseParams& noise) const;
  // The LiDAR's rotation from `from` to `to` (bias-corrected gyro); none where the samples do not cover.
  std::optional<Eigen::Matrix3d> lidar_rotation(int64_t from_ns, int64_t to_ns, const Eigen::Vector3d& gyro_bias,
                                                const Eigen::Isometry3d& T_lidar_imu) const;

 private:
  std::deque<ImuIn> samples_;
};

}  // namespace cdc::frontend
