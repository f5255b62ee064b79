#include "cdc/sim/trajectory.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

namespace cdc::sim {
SplineTrajectory::SplineTrajectory(std::vector<Eigen::Isometry3d> controls, double t0_s, double dt_s)
    : controls_(std::move(controls)), t0_(t0_s), dt_(dt_s) {
  if (controls_.size() < 4 || dt_ <= 0) {
    throw std::invalid_argument("a spline trajectory needs at least 4 control poses and a positive period");
  }
  omega_.resize(controls_.size(), Eigen::Vector3d::Zero());
  for (size_t i = 1; i < controls_.size(); ++i) {
    omega_[i] = geometry::so3_log(controls_[i - 1].rotation().transpose() * controls_[i].rotation());
  }
}

// Segment i covers [t0 + i dt, t0 + (i+1) dt) and uses controls i-1 .. i+2.
size_t SplineTrajectory::segment(double t, double& u) const {
  const double s = (t - t0_) / dt_;
  const double clamped = std::clamp(s, 1.0, static_cast<double>(controls_.size() - 2) - 1e-9);
  const size_t i = static_cast<size_t>(std::floor(clamped));
  u = clamped - static_cast<double>(i);
  return i;
}

Eigen::Isometry3d SplineTrajectory::pose(double t) const {
  double u = 0;
  const size_t i = segment(t, u);
  const double u2 = u * u, u3 = u2 * u;
  // Uniform cubic B-spline basis and its cumulative form.
  const double b0 = (1 - 3 * u + 3 * u2 - u3) / 6, b1 = (4 - 6 * u2 + 3 * u3) / 6,
               b2 = (1 + 3 * u + 3 * u2 - 3 * u3) / 6, b3 = u3 / 6;
  const double c1 = (5 + 3 * u - 3 * u2 + u3) / 6, c2 = (1 + 3 * u + 3 * u2 - 2 * u3) / 6, c3 = u3 / 6;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = b0 * controls_[i - 1].translation() + b1 * controls_[i].translation() +
                    b2 * controls_[i + 1].translation() + b3 * controls_[i + 2].translation();
  T.linear() = controls_[i - 1].rotation() * geometry::so3_exp(c1 * omega_[i]) * geometry::so3_exp(c2 * omega_[i + 1]) *
               geometry::so3_exp(c3 * omega_[i + 2]);
  return T;
}

Eigen::Vector3d SplineTrajectory::velocity(double t) const {
  double u = 0;
  const size_t i = segment(t, u);
  const double u2 = u * u;
  const double d0 = (-3 + 6 * u - 3 * u2) / 6, d1 = (-12 * u + 9 * u2) / 6, d2 = (3 + 6 * u - 9 * u2) / 6,
               d3 = 3 * u2 / 6;
  return (d0 * controls_[i - 1].translation() + d1 * controls_[i].translation() + d2 * controls_[i + 1].translation() +
          d3 * controls_[i + 2].translation()) /
         dt_;
}

Eigen::Vector3d SplineTrajectory::acceleration(double t) const {
  double u = 0;
  const size_t i = segment(t, u);
  const double a0 = (6 - 6 * u) / 6, a1 = (-12 + 18 * u) / 6, a2 = (6 - 18 * u) / 6, a3 = 6 * u / 6;
  return (a0 * controls_[i - 1].translation() + a1 * controls_[i].translation() + a2 * controls_[i + 1].translation() +
          a3 * controls_[i + 2].translation()) /
         (dt_ * dt_);
}

Eigen::Vector3d SplineTrajectory::angular_velocity(double t) const {
  // Central difference of the smooth rotation spline (error O(h^2)).
  const double h = 1e-5;
  const Eigen::Matrix3d Ra = pose(t - h).rotation(), Rb = pose(t + h).rotation();
  return geometry::so3_log(Ra.transpose() * Rb) / (2 * h);
}

std::vector<ImuSample> simulate_imu(const SplineTrajectory& tr, const Eigen::Isometry3d& T_body_imu, double t0,
                                    double t1, double rate_hz, const ImuNoise& n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> g(0.0, 1.0);
  auto gauss3 = [&] { return Eigen::Vector3d(g(rng), g(rng), g(rng)); };
  const double dt = 1.0 / rate_hz;
  const Eigen::Matrix3d R_bi = T_body_imu.rotation();
  const Eigen::Vector3d p_bi = T_body_imu.translation();
  Eigen::Vector3d ba = Eigen::Vector3d::Zero(), bg = Eigen::Vector3d::Zero();
  std::vector<ImuSample> out;
  for (double t = t0; t <= t1 + 1e-12; t += dt) {
    const Eigen::Isometry3d T = tr.pose(t);
    const Eigen::Vector3d w_b = tr.angular_velocity(t);
    // Lever arm: the IMU at p_bi feels a + alpha x r + w x (w x r) (world frame).
    const double h = 1e-4;
    const Eigen::Vector3d alpha_b = (tr.angular_velocity(t + h) - tr.angular_velocity(t - h)) / (2 * h);
    const Eigen::Vector3d a_b =
        T.rotation().transpose() * tr.acceleration(t) + alpha_b.cross(p_bi) + w_b.cross(w_b.cross(p_bi));
    const Eigen::Vector3d f_b = a_b - T.rotation().transpose() * kGravity;
    ImuSample s;
    s.t = t;
    s.accel = R_bi.transpose() * f_b + ba + gauss3() * n.accel_noise / std::sqrt(dt);
    s.gyro = R_bi.transpose() * w_b + bg + gauss3() * n.gyro_noise / std::sqrt(dt);
    out.push_back(s);
    ba += gauss3() * n.accel_bias_walk * std::sqrt(dt);
    bg += gauss3() * n.gyro_bias_walk * std::sqrt(dt);
  }
  return out;
}

}  // namespace cdc::sim
