// The IMU samples the front-end keeps: in time order, the old ones forgotten; preintegration and
// rotation only where the samples cover; and the IMU's motion over a sweep against the truth of an
// accelerating, turning drive.
#include "cdc/frontend/imu_buffer.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <deque>

namespace cdc::frontend {
namespace {

constexpr int64_t kMs = 1'000'000;

// Samples every 10 ms over [from, to] of a constant turn about the IMU's z axis.
void add_turn(ImuBuffer& imu, int64_t from_ns, int64_t to_ns, double yaw_rate) {
  for (int64_t t = from_ns; t <= to_ns; t += 10 * kMs)
    imu.add({t, Eigen::Vector3d(0, 0, yaw_rate), Eigen::Vector3d(0, 0, 9.81)}, 0);
}

TEST(ImuBuffer, KeepsSamplesInTimeOrderAndForgetsThoseNoSweepNeeds) {
  ImuBuffer imu;
  EXPECT_TRUE(imu.empty());
  EXPECT_TRUE(imu.add({100 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, 0));
  EXPECT_FALSE(imu.add({100 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, 0)) << "as old as the last";
  EXPECT_FALSE(imu.add({50 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, 0)) << "older than the last";
  EXPECT_EQ(imu.samples().size(), 1u);
  // With the latest sweep at 1.5 s, what lies more than half a second before it goes (the sample
  // held at 1.0 s stays).
  for (int64_t t = 110 * kMs; t <= 2000 * kMs; t += 10 * kMs)
    imu.add({t, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()}, 1500 * kMs);
  EXPECT_LE(imu.samples().front().stamp_ns, 1000 * kMs);
  EXPECT_GE(imu.samples()[1].stamp_ns, 1000 * kMs);
  EXPECT_EQ(imu.samples().back().stamp_ns, 2000 * kMs);
  imu.clear();
  EXPECT_TRUE(imu.empty());
}

TEST(ImuBuffer, PreintegratesOnlyWhatTheSamplesCover) {
  ImuBuffer imu;
  add_turn(imu, 0, 1000 * kMs, 0.5);
  const odometry::ImuNoiseParams noise;
  const auto pre = imu.preintegrate(200 * kMs, 500 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), noise);
  ASSERT_NE(pre, nullptr);
  EXPECT_NEAR(pre->dt(), 0.3, 1e-12);
  EXPECT_NEAR(geometry::rotation_angle(pre->delta_R(Eigen::Vector3d::Zero())), 0.15, 1e-9);
  EXPECT_EQ(imu.preintegrate(500 * kMs, 1500 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), noise), nullptr);
  EXPECT_EQ(imu.preintegrate(-100 * kMs, 500 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), noise), nullptr);
  EXPECT_EQ(imu.preintegrate(500 * kMs, 500 * kMs, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), noise), nullptr);
}

TEST(ImuBuffer, TheLidarsRotationIsTheBiasCorrectedTurnInItsFrame) {
  ImuBuffer imu;
  add_turn(imu, 0, 1000 * kMs, 0.5);
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();
  T_lidar_imu.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()).toRotationMatrix();
  T_lidar_imu.translation() = Eigen::Vector3d(0.3, 0, 0.1);
  const auto R = imu.lidar_rotation(200 * kMs, 600 * kMs, Eigen::Vector3d::Zero(), T_lidar_imu);
  ASSERT_TRUE(R.has_value());
  const Eigen::Matrix3d expected = T_lidar_imu.linear() *
                                   Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                                   T_lidar_imu.linear().transpose();
  EXPECT_TRUE(R->isApprox(expected, 1e-9));
  const auto still = imu.lidar_rotation(200 * kMs, 600 * kMs, Eigen::Vector3d(0, 0, 0.5), T_lidar_imu);
  ASSERT_TRUE(still.has_value());
  EXPECT_TRUE(still->isApprox(Eigen::Matrix3d::Identity(), 1e-9)) << "the bias is the whole turn";
  EXPECT_FALSE(imu.lidar_rotation(900 * kMs, 1100 * kMs, Eigen::Vector3d::Zero(), T_lidar_imu).has_value());
}

TEST(ImuBuffer, TheImusMotionOverASweepFollowsAnAcceleratingTurningDrive) {
  // Speed 8 +- 4 m/s (up to 3.2 m/s^2) with a yaw rate of up to 0.5 rad/s; the IMU 0.3 m behind the
  // LiDAR and turned 2 deg. The motion within a sweep from the IMU (start velocity and gravity
  // given, as the window gives them) against the truth, and against constant velocity.
  std::vector<Eigen::Isometry3d> controls;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 200; ++i) {
    controls.push_back(T);
    const double t = 0.1 * i;
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.translation().x() = 0.1 * (8.0 + 4.0 * std::sin(0.8 * t));
    step.linear() = Eigen::AngleAxisd(0.05 * std::sin(0.6 * t), Eigen::Vector3d::UnitZ()).toRotationMatrix() *
                    Eigen::AngleAxisd(0.004 * std::cos(0.9 * t), Eigen::Vector3d::UnitY()).toRotationMatrix();
    T = T * step;
  }
  const sim::SplineTrajectory traj(controls, 0.0, 0.1);
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();
  T_lidar_imu.translation() = Eigen::Vector3d(-0.3, 0.1, -0.2);
  T_lidar_imu.linear() =
      Eigen::AngleAxisd(2.0 * M_PI / 180, Eigen::Vector3d(0.3, 0.5, 1).normalized()).toRotationMatrix();
  std::deque<ImuIn> imu;
  for (const auto& m : sim::simulate_imu(traj, T_lidar_imu, 0.5, 18.0, 200.0, sim::ImuNoise::none(), 3)) {
    imu.push_back({static_cast<int64_t>(std::llround(m.t * 1e9)), m.gyro, m.accel});
  }
  double worst_imu = 0, worst_cv = 0, worst_rot = 0, worst_rot_only = 0;
  for (double t0 = 2.0; t0 < 17.0; t0 += 0.7) {
    const int64_t from = static_cast<int64_t>(std::llround(t0 * 1e9));
    std::vector<int64_t> to;
    for (int k = 1; k <= 4; ++k) to.push_back(from + k * 25'000'000);
    const auto inc = integrate_imu(imu, from, to, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    // The IMU's state at the start, as the window would give it.
    const Eigen::Isometry3d L0 = traj.pose(t0), I0 = L0 * T_lidar_imu;
    const Eigen::Vector3d v_imu =
        traj.velocity(t0) + L0.rotation() * traj.angular_velocity(t0).cross(T_lidar_imu.translation());
    const ImuStart start{I0.rotation().transpose() * v_imu, I0.rotation().transpose() * sim::kGravity};
    const geometry::Vector6d xi = geometry::se3_log(traj.pose(t0 - 0.1).inverse() * L0);  // constant velocity
    for (size_t k = 0; k < to.size(); ++k) {
      ASSERT_TRUE(inc[k].has_value());
      const double tau = 0.025 * static_cast<double>(k + 1);
      const Eigen::Isometry3d truth = L0.inverse() * traj.pose(t0 + tau);
      const Eigen::Isometry3d full = lidar_motion(*inc[k], T_lidar_imu, &start);
      const Eigen::Isometry3d rot_only = lidar_motion(*inc[k], T_lidar_imu, nullptr);
      const Eigen::Isometry3d cv = geometry::se3_exp(xi * (tau / 0.1));
      worst_imu = std::max(worst_imu, (truth.translation() - full.translation()).norm());
      worst_cv = std::max(worst_cv, (truth.translation() - cv.translation()).norm());
      worst_rot = std::max(worst_rot, geometry::rotation_angle(truth.rotation().transpose() * full.rotation()));
      worst_rot_only =
          std::max(worst_rot_only, geometry::rotation_angle(truth.rotation().transpose() * rot_only.rotation()));
      EXPECT_LT(rot_only.translation().norm(), 1e-12);
    }
  }
  std::printf("within a sweep: IMU %.2f mm, constant velocity %.2f mm; rotation %.4f deg\n", worst_imu * 1e3,
              worst_cv * 1e3, worst_rot * 180 / M_PI);
  EXPECT_LT(worst_imu, 2e-3);
  EXPECT_LT(worst_imu, 0.2 * worst_cv);
  // Sample-and-hold at 200 Hz lags the gyro by half a sample: with the yaw rate changing by up to
  // 0.3 rad/s^2 that is 0.3 * 0.0025 * 0.1 s = 7.5e-5 rad (0.0043 deg) over a sweep.
  EXPECT_LT(worst_rot, 0.01 * M_PI / 180);
  EXPECT_LT(worst_rot_only, 0.01 * M_PI / 180);
  // Instants the samples do not cover give nothing.
  const auto late = integrate_imu(imu, imu.back().stamp_ns - 1'000'000, {imu.back().stamp_ns + 1'000'000},
                                  Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_FALSE(late.front().has_value());
  const auto early = integrate_imu(imu, imu.front().stamp_ns - 1'000'000, {imu.front().stamp_ns},
                                   Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_FALSE(early.front().has_value());
}

}  // namespace
}  // namespace cdc::frontend
