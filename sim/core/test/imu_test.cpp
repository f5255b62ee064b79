#include "cdc/geometry/se3.hpp"
#include "cdc/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cdc::sim {
namespace {

// A car-like S curve with a little pitch and roll, sampled at 10 Hz.
SplineTrajectory curve() {
  std::vector<Eigen::Isometry3d> c;
  for (int i = 0; i < 60; ++i) {
    const double t = 0.1 * i;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(8 * t, 15 * std::sin(0.3 * t), 0.3 * std::sin(0.8 * t));
    T.linear() = (Eigen::AngleAxisd(0.6 * std::sin(0.3 * t), Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(0.05 * std::sin(1.1 * t), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(0.04 * std::cos(0.9 * t), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    c.push_back(T);
  }
  return SplineTrajectory(c, 0.0, 0.1);
}

TEST(Spline, VelocityAndAccelerationAreTheDerivativesOfPosition) {
  const SplineTrajectory s = curve();
  for (double t = 1.0; t < 4.0; t += 0.37) {
    const double h = 1e-4;
    const Eigen::Vector3d v_num = (s.pose(t + h).translation() - s.pose(t - h).translation()) / (2 * h);
    const Eigen::Vector3d a_num = (s.velocity(t + h) - s.velocity(t - h)) / (2 * h);
    EXPECT_LT((v_num - s.velocity(t)).norm(), 1e-6);
    EXPECT_LT((a_num - s.acceleration(t)).norm(), 1e-5);
  }
}

TEST(Imu, IntegratingNoiseFreeImuReproducesTheTrajectoryOverOneSecond) {
  const SplineTrajectory s = curve();
  Eigen::Isometry3d T_body_imu = Eigen::Isometry3d::Identity();
  T_body_imu.translation() = Eigen::Vector3d(0.2, -0.1, 0.3);  // a known extrinsic with a lever arm
  T_body_imu.linear() = Eigen::AngleAxisd(0.1, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  const double t0 = 2.0, t1 = 3.0, rate = 400.0;
  const auto imu = simulate_imu(s, T_body_imu, t0, t1, rate, ImuNoise::none(), 1);
  ASSERT_EQ(imu.size(), 401u);
  // Integrate the IMU's own pose (world <- imu) from the true initial state.
  auto imu_pose = [&](double t) { return s.pose(t) * T_body_imu; };
  Eigen::Matrix3d R = imu_pose(t0).rotation();
  Eigen::Vector3d p = imu_pose(t0).translation();
  const double h = 1e-5;
  Eigen::Vector3d v = (imu_pose(t0 + h).translation() - imu_pose(t0 - h).translation()) / (2 * h);
  const double dt = 1.0 / rate;
  for (size_t k = 0; k + 1 < imu.size(); ++k) {
    const Eigen::Vector3d w_mid = 0.5 * (imu[k].gyro + imu[k + 1].gyro);
    const Eigen::Matrix3d R_next = R * geometry::so3_exp(w_mid * dt);
    const Eigen::Vector3d a0 = R * imu[k].accel + kGravity;
    const Eigen::Vector3d a1 = R_next * imu[k + 1].accel + kGravity;
    p += v * dt + (2 * a0 + a1) * dt * dt / 6;
    v += 0.5 * (a0 + a1) * dt;
    R = R_next;
  }
  const Eigen::Isometry3d truth = imu_pose(t1);
  const double pos_err = (p - truth.translation()).norm();
  const double rot_err_deg = Eigen::AngleAxisd(truth.rotation().transpose() * R).angle() * 180 / M_PI;
  std::printf("after 1 s: position error %.4f m, rotation error %.4f deg\n", pos_err, rot_err_deg);
  EXPECT_LT(pos_err, 0.01);
  EXPECT_LT(rot_err_deg, 0.1);
}

TEST(Imu, NoiseHasTheConfiguredDensity) {
  const SplineTrajectory s = curve();
  const double rate = 200.0;
  const auto clean = simulate_imu(s, Eigen::Isometry3d::Identity(), 1.0, 4.0, rate, ImuNoise::none(), 1);
  ImuNoise n = ImuNoise::none();
  n.gyro_noise = 1e-3;
  const auto noisy = simulate_imu(s, Eigen::Isometry3d::Identity(), 1.0, 4.0, rate, n, 1);
  double sq = 0;
  for (size_t k = 0; k < clean.size(); ++k) {
    sq += (noisy[k].gyro - clean[k].gyro).squaredNorm();
  }
  const double sigma = std::sqrt(sq / (3.0 * static_cast<double>(clean.size())));
  EXPECT_NEAR(sigma, 1e-3 * std::sqrt(rate), 0.1 * 1e-3 * std::sqrt(rate));
}

}  // namespace
}  // namespace cdc::sim
