// Motion prediction: the motion from the previous sweep to this one, from which registration
// starts and deskewing takes the motion over the sweep. Once the sliding-window IMU estimator
// (imu_window.hpp) runs: its latest state propagated with the bias-corrected IMU, unless that lies
// implausibly far from constant velocity (a window gone wrong). Otherwise: constant velocity, with
// the IMU's rotation where the samples cover the interval. The predictor also keeps the window:
// each sweep's registered pose goes into it.
#pragma once

#include "cdc/frontend/deskewing.hpp"
#include "cdc/frontend/frontend_types.hpp"
#include "cdc/frontend/imu_buffer.hpp"
#include "cdc/frontend/imu_window.hpp"
#include "cdc/odometry/imu_preintegration.hpp"
#include "cdc/odometry/registration.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <optional>

namespace cdc::frontend {

struct Prediction {
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();  // the motion since the previous sweep
  std::unique_ptr<odometry::ImuPreintegration> pre;         // the IMU since the previous sweep, for the window
  std::optional<ImuStart> imu_start;                        // the IMU's state at the sweep's start (imu_deskew)
};

class MotionPredictor {
 public:
  explicit MotionPredictor(const FrontendParams& params);

  // The motion from the previous sweep (at last_ns) to this one, dt later (counted in stats).
  Prediction predict(int64_t last_ns, int64_t stamp_ns, double dt, const ImuBuffer& imu, FrontendStats& stats) const;
  // The motion found between the last two sweeps, dt apart: constant velocity continues it.
  void record_motion(const Eigen::Isometry3d& delta, double dt);
  // A sweep's pose into the window, with the registration's information (a sweep whose
  // registration failed gets a weak one, so the IMU carries it) and the IMU since the previous
  // sweep (`pre`, none where it does not cover). Nothing without IMU samples or with the window off.
  void update_window(int64_t stamp_ns, const Eigen::Isometry3d& T, const odometry::RegistrationResult& reg,
                     std::unique_ptr<odometry::ImuPreintegration> pre, const ImuBuffer& imu, FrontendStats& stats);
  // What deskewing takes from the IMU with the window's biases; `start`: the IMU's state at the
  // sweep's start, for the IMU's whole motion.
  DeskewImu deskew_imu(const ImuBuffer& imu, const ImuStart* start) const;

  // The window's latest state and gravity once it runs; gravity once it is known.
  std::optional<ImuState> imu_state() const;
  std::optional<Eigen::Vector3d> running_gravity() const;
  std::optional<Eigen::Vector3d> gravity() const;

 private:
  // The window's prediction, if plausible against the constant-velocity `delta`.
  std::optional<Eigen::Isometry3d> window_prediction(const odometry::ImuPreintegration& pre,
                                                     const Eigen::Isometry3d& delta, Prediction& out,
                                                     FrontendStats& stats) const;

  FrontendParams p_;
  std::unique_ptr<ImuWindow> window_;
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();      // the window's latest estimate
  Eigen::Isometry3d delta_ = Eigen::Isometry3d::Identity();  // the last motion between sweeps
  double dt_last_ = 0.1;
};

}  // namespace cdc::frontend
