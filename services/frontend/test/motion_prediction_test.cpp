// Motion prediction: constant velocity from the last motion, the gyro's rotation where the IMU
// covers, the sliding window's prediction once it runs (and the IMU's state at the sweep's start
// for IMU deskewing), and constant velocity again when the window's prediction is implausible.
#include "cdc/frontend/motion_prediction.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace cdc::frontend {
namespace {

int64_t ns(double t) { return static_cast<int64_t>(std::llround(t * 1e9)); }

Eigen::Isometry3d forward_and_turn(double metres, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = metres;
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// A registration as the window takes it: converged, a centimetre and a few millidegrees.
odometry::RegistrationResult registered() {
  odometry::RegistrationResult reg;
  reg.converged = true;
  reg.correspondences = 1000;
  reg.hessian.diagonal() << 500, 500, 500, 5e4, 5e4, 5e4;
  return reg;
}

TEST(MotionPrediction, ConstantVelocityContinuesTheLastMotion) {
  MotionPredictor predictor{FrontendParams{}};
  const ImuBuffer no_imu;
  FrontendStats stats;
  const Eigen::Isometry3d D = forward_and_turn(1.0, 0.05);
  predictor.record_motion(D, 0.1);
  const Prediction pr = predictor.predict(ns(1.0), ns(1.2), 0.2, no_imu, stats);
  EXPECT_TRUE(pr.delta.isApprox(D * D, 1e-9)) << "twice the motion in twice the time";
  EXPECT_EQ(pr.pre, nullptr);
  EXPECT_FALSE(pr.imu_start.has_value());
  predictor.update_window(ns(1.2), D, registered(), nullptr, no_imu, stats);
  EXPECT_FALSE(predictor.imu_state().has_value()) << "no IMU, no window";
  EXPECT_EQ(stats.imu_predictions + stats.imu_predictions_rejected, 0u);
}

TEST(MotionPrediction, TheGyrosRotationWhereTheImuCovers) {
  FrontendParams p;
  p.imu_window = false;
  MotionPredictor predictor(p);
  ImuBuffer imu;
  for (int64_t t = 0; t <= ns(0.3); t += ns(0.005))
    imu.add({t, Eigen::Vector3d(0, 0, 1.0), Eigen::Vector3d(0, 0, 9.81)}, 0);
  FrontendStats stats;
  predictor.record_motion(forward_and_turn(1.0, 0.3), 0.1);
  const Prediction pr = predictor.predict(ns(0.1), ns(0.2), 0.1, imu, stats);
  EXPECT_TRUE(pr.delta.linear().isApprox(forward_and_turn(0, 0.1).linear(), 1e-9)) << "the gyro's 0.1 rad";
  EXPECT_TRUE(pr.delta.translation().isApprox(Eigen::Vector3d(1.0, 0, 0), 1e-9)) << "constant velocity's translation";
  predictor.update_window(ns(0.2), pr.delta, registered(), nullptr, imu, stats);
  EXPECT_FALSE(predictor.imu_state().has_value()) << "the window is off";
}

// A drive at 6-10 m/s, winding, with its IMU (noiseless, at 200 Hz), fed sweep by sweep as the
// core feeds the predictor: the IMU up to the sweep's end, the prediction, the registered pose
// (here the true one) into the window, the motion recorded.
struct Drive {
  sim::SplineTrajectory traj;
  std::vector<sim::ImuSample> samples;
  size_t next = 0;
  ImuBuffer imu;
  Eigen::Isometry3d T0;
  FrontendStats stats;
  Drive() {
    std::vector<Eigen::Isometry3d> controls;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int i = 0; i < 120; ++i) {
      controls.push_back(T);
      T = T * forward_and_turn(0.1 * (8.0 + 2.0 * std::sin(0.05 * i)), 0.03 * std::sin(0.03 * i));
    }
    traj = sim::SplineTrajectory(controls, 0.0, 0.1);
    samples = sim::simulate_imu(traj, Eigen::Isometry3d::Identity(), 0.0, 11.0, 200.0, sim::ImuNoise::none(), 1);
    T0 = traj.pose(1.0);
  }
  Eigen::Isometry3d lidar(double t) const { return T0.inverse() * traj.pose(t); }
  // Sweep k (at 1.0 + 0.1 k s) through the predictor; the prediction's error against the truth [m].
  double sweep(MotionPredictor& predictor, int k, Prediction* out = nullptr) {
    const double t = 1.0 + 0.1 * k;
    while (next < samples.size() && samples[next].t <= t + 0.1) {
      imu.add({ns(samples[next].t), samples[next].gyro, samples[next].accel}, ns(t - 0.1));
      ++next;
    }
    Prediction pr;
    double error = 0;
    if (k > 0) {
      pr = predictor.predict(ns(t - 0.1), ns(t), 0.1, imu, stats);
      error = ((lidar(t - 0.1) * pr.delta).inverse() * lidar(t)).translation().norm();
      predictor.record_motion(lidar(t - 0.1).inverse() * lidar(t), 0.1);
    }
    if (out != nullptr) out->imu_start = pr.imu_start;
    predictor.update_window(ns(t), lidar(t), registered(), std::move(pr.pre), imu, stats);
    return error;
  }
};

TEST(MotionPrediction, TheWindowPredictsOnceItRuns) {
  Drive d;
  MotionPredictor predictor{FrontendParams{}};
  double worst = 0;
  for (int k = 0; k < 70; ++k) {
    const uint64_t before = d.stats.imu_predictions;
    const double e = d.sweep(predictor, k);
    if (d.stats.imu_predictions > before) worst = std::max(worst, e);
  }
  std::printf("%llu of 70 sweeps predicted by the window, worst error %.4f m\n",
              static_cast<unsigned long long>(d.stats.imu_predictions), worst);
  // Gravity is aligned over the first 30 sweeps; from then on the window predicts.
  EXPECT_GE(d.stats.imu_predictions, 35u);
  EXPECT_EQ(d.stats.imu_predictions_rejected, 0u);
  EXPECT_EQ(d.stats.imu_window_restarts, 0u);
  EXPECT_LT(worst, 0.01);
  ASSERT_TRUE(predictor.imu_state().has_value());
  ASSERT_TRUE(predictor.running_gravity().has_value());
  ASSERT_TRUE(predictor.gravity().has_value());
  const Eigen::Vector3d g_true = d.T0.rotation().transpose() * sim::kGravity;
  EXPECT_LT((*predictor.running_gravity() - g_true).norm(), 0.1);
  // Deskewing takes the window's biases, the accelerometer's only with the IMU's state.
  const DeskewImu di = predictor.deskew_imu(d.imu, nullptr);
  EXPECT_EQ(di.imu, &d.imu);
  EXPECT_EQ(di.gyro_bias, predictor.imu_state()->bg);
  EXPECT_EQ(di.accel_bias, Eigen::Vector3d::Zero());
}

TEST(MotionPrediction, TheWindowGivesTheImusStateAtTheSweepsStartForImuDeskewing) {
  Drive d;
  FrontendParams p;
  p.imu_deskew = true;
  MotionPredictor predictor(p);
  Prediction last;
  for (int k = 0; k < 50; ++k) d.sweep(predictor, k, &last);
  ASSERT_TRUE(last.imu_start.has_value());
  const double t = 1.0 + 0.1 * 49;
  const Eigen::Matrix3d R_body = d.traj.pose(t).rotation().transpose();
  EXPECT_LT((last.imu_start->velocity - R_body * d.traj.velocity(t)).norm(), 0.05);
  EXPECT_LT((last.imu_start->gravity - R_body * sim::kGravity).norm(), 0.1);
}

TEST(MotionPrediction, AnImplausibleWindowPredictionIsNotUsed) {
  Drive d;
  MotionPredictor predictor{FrontendParams{}};
  for (int k = 0; k < 50; ++k) d.sweep(predictor, k);
  ASSERT_TRUE(predictor.imu_state().has_value());
  // The last motion recorded 3 m off what the IMU says: the window's prediction lies beyond
  // max_imu_prediction_gap_m of constant velocity and is not used.
  const Eigen::Isometry3d wrong = forward_and_turn(4.0, 0.0);
  predictor.record_motion(wrong, 0.1);
  const uint64_t rejected = d.stats.imu_predictions_rejected;
  const Prediction pr = predictor.predict(ns(5.9), ns(6.0), 0.1, d.imu, d.stats);
  EXPECT_EQ(d.stats.imu_predictions_rejected, rejected + 1);
  EXPECT_TRUE(pr.delta.translation().isApprox(wrong.translation(), 1e-9)) << "constant velocity";
  EXPECT_FALSE(pr.imu_start.has_value());
}

}  // namespace
}  // namespace cdc::frontend
