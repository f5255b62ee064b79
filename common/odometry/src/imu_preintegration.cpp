#include "cdc/odometry/imu_preintegration.hpp"

#include "cdc/geometry/se3.hpp"

namespace cdc::odometry {

using geometry::hat;
using geometry::so3_exp;

namespace {

// Right Jacobian of SO(3).
Eigen::Matrix3d right_jacobian(const Eigen::Vector3d& phi) {
  const double th = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (th < 1e-8) return Eigen::Matrix3d::Identity() - 0.5 * W;
  return Eigen::Matrix3d::Identity() - (1 - std::cos(th)) / (th * th) * W +
         (th - std::sin(th)) / (th * th * th) * W * W;
}

}  // namespace

ImuPreintegration::ImuPreintegration(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba, const ImuNoiseParams& noise)
    : noise_(noise), bg_(bg), ba_(ba) {}

void ImuPreintegration::integrate(const Eigen::Vector3d& gyro, const Eigen::Vector3d& accel, double dt) {
  if (dt <= 0) return;
  const Eigen::Vector3d w = gyro - bg_, a = accel - ba_;
  const Eigen::Matrix3d dRi = so3_exp(w * dt);
  const Eigen::Matrix3d Jr = right_jacobian(w * dt);
  // Covariance propagation (rotation, velocity, position), discrete-time noise densities.
  Matrix9d A = Matrix9d::Identity();
  Eigen::Matrix<double, 9, 6> B = Eigen::Matrix<double, 9, 6>::Zero();
  A.block<3, 3>(0, 0) = dRi.transpose();
  A.block<3, 3>(3, 0) = -d_.R * hat(a) * dt;
  A.block<3, 3>(6, 0) = -0.5 * d_.R * hat(a) * dt * dt;
  A.block<3, 3>(6, 3) = Eigen::Matrix3d::Identity() * dt;
  B.block<3, 3>(0, 0) = Jr * dt;
  B.block<3, 3>(3, 3) = d_.R * dt;
  B.block<3, 3>(6, 3) = 0.5 * d_.R * dt * dt;
  Eigen::Matrix<double, 6, 6> Q = Eigen::Matrix<double, 6, 6>::Zero();
  Q.diagonal().head<3>().setConstant(noise_.gyro_noise * noise_.gyro_noise / dt);
  Q.diagonal().tail<3>().setConstant(noise_.accel_noise * noise_.accel_noise / dt);
  cov_ = A * cov_ * A.transpose() + B * Q * B.transpose();
  // Bias Jacobians (before updating the increments they depend on).
  dp_dba_ += dv_dba_ * dt - 0.5 * d_.R * dt * dt;
  dp_dbg_ += dv_dbg_ * dt - 0.5 * d_.R * hat(a) * dR_dbg_ * dt * dt;
  dv_dba_ += -d_.R * dt;
  dv_dbg_ += -d_.R * hat(a) * dR_dbg_ * dt;
  dR_dbg_ = dRi.transpose() * dR_dbg_ - Jr * dt;
  // Increments.
  d_.step(dRi, a, dt);
}

Eigen::Matrix3d ImuPreintegration::delta_R(const Eigen::Vector3d& bg) const {
  return d_.R * so3_exp(dR_dbg_ * (bg - bg_));
}

Eigen::Vector3d ImuPreintegration::delta_v(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba) const {
  return d_.v + dv_dbg_ * (bg - bg_) + dv_dba_ * (ba - ba_);
}

Eigen::Vector3d ImuPreintegration::delta_p(const Eigen::Vector3d& bg, const Eigen::Vector3d& ba) const {
  return d_.p + dp_dbg_ * (bg - bg_) + dp_dba_ * (ba - ba_);
}

void ImuPreintegration::predict(const Eigen::Matrix3d& Ri, const Eigen::Vector3d& vi, const Eigen::Vector3d& pi,
                                const Eigen::Vector3d& g, Eigen::Matrix3d& Rj, Eigen::Vector3d& vj,
                                Eigen::Vector3d& pj) const {
  Rj = geometry::project_to_so3(Ri * d_.R);
  vj = vi + g * d_.dt + Ri * d_.v;
  pj = pi + vi * d_.dt + 0.5 * g * d_.dt * d_.dt + Ri * d_.p;
}

}  // namespace cdc::odometry
