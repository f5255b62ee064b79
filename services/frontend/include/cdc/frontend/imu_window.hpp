// The front-end's sliding-window factor graph (Ceres), as LIO-SAM's IMU preintegration node does it:
// the IMU states (orientation, position, velocity, gyro and accelerometer biases) of the last
// sweeps, linked by IMU preintegration factors with bias random walk, and anchored by LiDAR
// odometry factors (each sweep's registered pose, information from the registration's Hessian).
//
// Gravity: the registered poses are in the map's frame, the first sweep's, so gravity is a nearly
// constant vector in it, found once by a linear alignment over the first align_sweeps sweeps (LiDAR
// positions against the preintegrated increments, velocities unknown), then refined by every window
// (its direction a parameter on the sphere, drawn to its last estimate). When the map's frame tilts
// (registration drifting in roll or pitch), the refined gravity turns with it: the front-end levels
// its odometry with that (FrontendParams::level_with_gravity). The oldest state of the window is the anchor: its
// pose is held, its velocity and biases carry a prior at their previous estimate (a conservative
// stand-in for marginalisation), and the biases a weak zero-mean prior of a MEMS IMU's size.
//
// What it gives the front-end: the latest velocity and biases, so the next sweep is predicted
// (and deskewed) from the bias-corrected IMU instead of a constant-velocity model. Its poses do not
// replace the registered ones: the map stays on the LiDAR's poses (as in LIO-SAM, where the IMU
// graph serves the prediction and the LiDAR pose is the odometry).
#pragma once

#include "cdc/odometry/imu_preintegration.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <deque>
#include <memory>
#include <vector>

namespace ceres {
class Manifold;
class Problem;
}  // namespace ceres

namespace cdc::frontend {

struct ImuState {
  int64_t stamp_ns = 0;
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();  // odometry frame <- IMU body
  Eigen::Vector3d p = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
  Eigen::Vector3d bg = Eigen::Vector3d::Zero(), ba = Eigen::Vector3d::Zero();
};

struct ImuWindowParams {
  size_t size = 10;                // sweeps in the window (1 s at 10 Hz)
  size_t align_sweeps = 30;        // sweeps the gravity alignment spans (at least 3; longer averages the LiDAR's noise)
  odometry::ImuNoiseParams noise;  // of the IMU's samples (inflated when the IMU model is rough)
  double gravity = 9.80665;        // [m/s^2]
  double max_gravity_error = 0.5;  // [m/s^2] an alignment whose |g| is further off is retried later
  // After the alignment, every window refines gravity's direction, drawn to its last estimate with
  // this sigma: the alignment's few seconds of early, noisy LiDAR poses can leave it degrees off.
  bool refine_gravity = true;
  double gravity_prior_sigma = 0.05;  // [m/s^2]
  int max_iterations = 10;
  double gyro_bias_sigma = 0.01;          // [rad/s] zero-mean bias priors
  double accel_bias_sigma = 0.1;          // [m/s^2]
  double anchor_velocity_sigma = 0.05;    // [m/s] the oldest state's velocity at its last estimate
  double anchor_gyro_bias_sigma = 2e-3;   // [rad/s] ... and its biases
  double anchor_accel_bias_sigma = 0.02;  // [m/s^2]
  double max_gyro_bias = 0.1;             // [rad/s] estimates beyond these restart the window
  double max_accel_bias = 1.0;            // [m/s^2]
};

class ImuWindow {
 public:
  using Matrix6d = Eigen::Matrix<double, 6, 6>;
  ImuWindow(const ImuWindowParams& params, const Eigen::Isometry3d& T_lidar_imu);
  ~ImuWindow();

  // A sweep's registered LiDAR pose (odometry frame) with its information ((t, r) order, right
  // perturbation), and the preintegration since the previous sweep (none: the IMU did not cover
  // the interval, and the window starts again here). Optimises the window. A non-finite pose or
  // information empties the window (counted as a restart).
  void add(int64_t stamp_ns, const Eigen::Isometry3d& T_odom_lidar, const Matrix6d& information,
           std::unique_ptr<odometry::ImuPreintegration> since_previous);

  // Gravity is known and the latest state has been estimated with it.
  bool ready() const noexcept { return gravity_known_ && states_.size() >= 2 && solved_; }
  const ImuState& latest() const { return states_.back().state; }
  const Eigen::Vector3d& gravity() const noexcept { return g_; }
  bool gravity_known() const noexcept { return gravity_known_; }
  // The latest state's LiDAR pose; the IMU state after `preint` from it (biases held), and its
  // LiDAR pose.
  Eigen::Isometry3d latest_lidar() const;
  ImuState predict(const odometry::ImuPreintegration& preint) const;
  Eigen::Isometry3d predict_lidar(const odometry::ImuPreintegration& preint) const;
  uint64_t restarts() const noexcept { return restarts_; }
  uint64_t solves() const noexcept { return solves_; }

 private:
  struct Node {
    ImuState state;
    Eigen::Isometry3d T_odom_lidar;
    Matrix6d sqrt_information;
    std::unique_ptr<odometry::ImuPreintegration> preint;  // from the previous node
    double qbuf[4], pbuf[3], vbuf[3], bbuf[6];
  };
  struct Interval {  // what the gravity alignment keeps of each interval
    Eigen::Matrix3d R_from;
    Eigen::Vector3d p_from, p_to, dv, dp;
    double dt;
  };
  bool align_gravity();
  void optimise();
  void add_states(ceres::Problem& problem, ceres::Manifold* quaternion);
  void add_imu_factors(ceres::Problem& problem);
  void add_gravity(ceres::Problem& problem, ceres::Manifold* sphere);
  void add_anchor(ceres::Problem& problem);
  bool plausible_solution() const;
  void take_solution();
  void start_over();  // empties the window (gravity stays known), counted as a restart
  void restart();     // starts over from the latest sweep

  ImuWindowParams p_;
  Eigen::Isometry3d T_lidar_imu_, T_imu_lidar_;
  std::deque<Node> states_;
  std::vector<Interval> alignment_;
  Eigen::Vector3d g_ = Eigen::Vector3d(0, 0, -9.80665);
  double gbuf[3];
  bool gravity_known_ = false, solved_ = false;
  uint64_t restarts_ = 0, solves_ = 0;
};

}  // namespace cdc::frontend
