// IMU preintegration on manifold (Forster et al., RSS 2015): the relative rotation, velocity and
// position increments between two instants from gyro and accelerometer samples, their covariance,
// and their first-order Jacobians with respect to the biases (so a bias update does not need a
// re-integration). Frames: the IMU body frame b, a gravity-aligned world w with g = (0, 0, -9.81).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>

namespace cdc::odometry {

struct ImuNoiseParams {
  double gyro_noise = 1.7e-4;       // [rad/s/sqrt(Hz)]
  double accel_noise = 2.0e-3;      // [m/s^2/sqrt(Hz)]
  double gyro_bias_walk = 2.0e-5;   // [rad/s^2/sqrt(Hz)]
  double accel_bias_walk = 3.0e-4;  // [m/s^3/sqrt(Hz)]
};

// The mean increments of bias-corrected IMU samples held over intervals (sample-and-hold), in the
// body frame at the start, gravity excluded: rotation R, velocity v and position p after dt seconds.
// The body's own motion is then p_start + v_start dt + g dt^2 / 2 + R_start p (and likewise v).
struct ImuDelta {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d v = Eigen::Vector3d::Zero(), p = Eigen::Vector3d::Zero();
  double dt = 0;
  // Acceleration a (bias removed, body frame) held over h seconds, during which the body turns by dR.
  void step(const Eigen::Matrix3d& dR, const Eigen::Vector3d& a, double h) {
    p += v * h + 0.5 * R * a * h * h;
    v += R * a * h;
    R = R * dR;
    dt += h;
  }
};

class ImuPreintegration {
 public:
  using Matrix9d = Eigen::Matrix<double, 9, 9>;

  ImuPreintegration(const Eigen::Vector3d& gyro_bias, const Eigen::Vector3d& accel_bias,
                    const ImuNoiseParams& noise = {});

  // One sample held over dt seconds (sample-and-hold).
  void integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt);

  double dt() const noexcept { return d_.dt; }
  // Increments corrected to first order for other biases.
  Eigen::Matrix3d delta_R(const Eigen::Vector3d& bg) const;
  Eigen::Vector3d delta_v(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba) const;
  Eigen::Vector3d delta_p(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba) const;
  const Matrix9d& covariance() const noexcept { return cov_; }  // (rotation, velocity, position)
  const Eigen::Vector3d& gyro_bias() const noexcept { return bg_; }
  const Eigen::Vector3d& accel_bias() const noexcept { return ba_; }
  // First-order bias Jacobians: delta_R(bg) = dR Exp(dR_dbg (bg - gyro_bias())), and so on.
  const Eigen::Matrix3d& dR_dbg() const noexcept { return dR_dbg_; }
  const Eigen::Matrix3d& dv_dbg() const noexcept { return dv_dbg_; }
  const Eigen::Matrix3d& dv_dba() const noexcept { return dv_dba_; }
  const Eigen::Matrix3d& dp_dbg() const noexcept { return dp_dbg_; }
  const Eigen::Matrix3d& dp_dba() const noexcept { return dp_dba_; }

  // The state at the end from the state at the start: R_j, v_j, p_j.
  void predict(const Eigen::Matrix3d& Ri, const Eigen::Vector3d& vi, const Eigen::Vector3d& pi,
               const Eigen::Vector3d& g, Eigen::Matrix3d& Rj, Eigen::Vector3d& vj, Eigen::Vector3d& pj) const;

 private:
  ImuNoiseParams noise_;
  Eigen::Vector3d bg_, ba_;
  ImuDelta d_;  // the increments at the biases integrated with
  Eigen::Matrix3d dR_dbg_ = Eigen::Matrix3d::Zero(), dv_dbg_ = Eigen::Matrix3d::Zero(),
                  dv_dba_ = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d dp_dbg_ = Eigen::Matrix3d::Zero(), dp_dba_ = Eigen::Matrix3d::Zero();
  Matrix9d cov_ = Matrix9d::Zero();
};

}  // namespace cdc::odometry
