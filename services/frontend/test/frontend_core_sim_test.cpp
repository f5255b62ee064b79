// The front-end core on long simulated drives with real motion distortion: deskewing undoes the
// motion, the odometry follows the truth, and a 2 m / 5 deg back-end correction is taken in
// smoothly (every per-scan change bounded by the fusion thresholds) until it is reached; levelled
// with gravity, a correction turns the odometry about the vertical only. With a biased IMU, the
// sliding window predicts the sweeps and finds the gyro bias; levelling holds the tilt of a
// miscalibrated LiDAR. At 2 Hz, hand-held, the recovery keeps the track through sharp turns.
#include "simulated_drive.hpp"

#include "cdc/frontend/frontend_core.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>

namespace cdc::frontend {
namespace {

// Sweep k of a drive (at 0.2 + 0.1 k s) with the IMU samples up to its end, into a core; keeps the
// worst position error of the odometry against the truth.
struct ImuFeed {
  Drive& d;
  std::vector<sim::ImuSample> imu;
  FrontendCore& core;
  Eigen::Isometry3d T0 = d.traj.pose(0.2);
  size_t next = 0;
  double worst = 0;
  ScanOut last{};
  void scan(int k) {
    const double t = 0.2 + 0.1 * k;
    while (next < imu.size() && imu[next].t <= t + 0.1) {
      core.add_imu({static_cast<int64_t>(std::llround(imu[next].t * 1e9)), imu[next].gyro, imu[next].accel});
      ++next;
    }
    last = core.process(static_cast<int64_t>(std::llround(t * 1e9)), d.sweep(t));
    worst = std::max(worst, ((T0.inverse() * d.traj.pose(t)).inverse() * last.T_odom_raw).translation().norm());
  }
};

// The default parameters but for one.
template <typename Field, typename Value>
FrontendParams params_with(Field FrontendParams::*field, Value value) {
  FrontendParams p;
  p.*field = value;
  return p;
}

// Noiseless 200 Hz IMU samples of a drive from 0 to `until` [s], the IMU frame at the body frame.
std::vector<sim::ImuSample> noiseless_imu(const Drive& d, double until, uint64_t seed) {
  return sim::simulate_imu(d.traj, Eigen::Isometry3d::Identity(), 0.0, until, 200.0, sim::ImuNoise{}, seed);
}

double run_error(Drive& d, bool deskew, int scans) {
  FrontendCore core(params_with(&FrontendParams::deskew, deskew));
  const Eigen::Isometry3d T0 = d.traj.pose(0.2);
  double worst = 0;
  for (int k = 0; k < scans; ++k) {
    const double t = 0.2 + 0.1 * k;
    const ScanOut o = core.process(static_cast<int64_t>(t * 1e9), d.sweep(t));
    const Eigen::Isometry3d truth = T0.inverse() * d.traj.pose(t);
    worst = std::max(worst, (truth.inverse() * o.T_odom_raw).translation().norm());
  }
  return worst;
}

TEST(Frontend, DeskewingUndoesTheMotionDuringASweep) {
  // 15 m/s with turns: without deskewing a sweep smears by 1.5 m.
  Drive d(15.0, 0.6, 8.0);
  const double with = run_error(d, true, 60), without = run_error(d, false, 60);
  std::printf("worst position error over 90 m: %.3f m deskewed, %.3f m raw\n", with, without);
  EXPECT_LT(with, 0.25);
  EXPECT_LT(with, 0.5 * without);
}

TEST(Frontend, ACorrectionIsTakenInSmoothlyAndReached) {
  Drive d(8.0, 0.3, 10.0);
  FrontendParams p;
  p.fusion = {0.10, 1.0 * M_PI / 180};
  FrontendCore core(p);
  std::optional<KeyframeOut> corrected_kf;
  Eigen::Isometry3d last_pub = Eigen::Isometry3d::Identity(), last_raw = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();  // corrected = offset * raw
  offset.translation() = Eigen::Vector3d(2.0 * std::cos(0.3), 2.0 * std::sin(0.3), 0.0);
  offset.linear() = Eigen::AngleAxisd(5.0 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  double worst_step_t = 0, worst_step_r = 0;
  int reached_at = -1;
  for (int k = 0; k < 90; ++k) {
    const double t = 0.2 + 0.1 * k;
    const ScanOut o = core.process(static_cast<int64_t>(t * 1e9), d.sweep(t));
    if (k == 20) {
      ASSERT_TRUE(o.keyframe.has_value() || corrected_kf.has_value());
    }
    if (o.keyframe && !corrected_kf && k >= 20) {
      corrected_kf = o.keyframe;
      // The back-end says: this keyframe is really at offset * its pose (T_world_robot = I).
      ASSERT_TRUE(
          core.set_correction(o.keyframe->id, offset * o.keyframe->T_odom_keyframe, Eigen::Isometry3d::Identity()));
    } else if (k > 0) {
      // Beyond the odometry's own increment, the published pose moves by at most the thresholds.
      const Eigen::Isometry3d expected = last_pub * (last_raw.inverse() * o.T_odom_raw);
      const Eigen::Isometry3d step = expected.inverse() * o.T_odom_base;
      worst_step_t = std::max(worst_step_t, step.translation().norm());
      worst_step_r = std::max(worst_step_r, geometry::rotation_angle(step.rotation()));
    }
    if (corrected_kf && o.T_world_base) {
      const Eigen::Isometry3d gap = (offset * o.T_odom_raw).inverse() * o.T_odom_base;
      if (reached_at < 0 && gap.translation().norm() < 0.01 && geometry::rotation_angle(gap.rotation()) < 1e-3)
        reached_at = k;
    }
    last_pub = o.T_odom_base;
    last_raw = o.T_odom_raw;
  }
  ASSERT_TRUE(corrected_kf.has_value());
  std::printf("largest step beyond odometry: %.3f m, %.3f deg; correction reached at scan %d\n", worst_step_t,
              worst_step_r * 180 / M_PI, reached_at);
  // pos_max 0.10 m; the rotation step also moves the position (lever of the slerp about the pose).
  EXPECT_LE(worst_step_t, 0.10 + 1e-6);
  EXPECT_LE(worst_step_r, 1.0 * M_PI / 180 + 1e-6);
  EXPECT_GT(worst_step_t, 0.05) << "the correction was applied";
  EXPECT_GE(reached_at, 20 + 20) << "2 m cannot be covered in fewer than 20 scans of 0.1 m";
  EXPECT_GT(reached_at, 0) << "never reached the correction";
  EXPECT_LT(reached_at, 80);
  EXPECT_EQ(core.stats().corrections, 1u);
  EXPECT_FALSE(core.set_correction(9999, Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity()));
}

TEST(Frontend, ALevelledOdometryTakesACorrectionsTurnAboutTheVerticalOnly) {
  // Levelled with gravity, the odometry's roll and pitch are observed; a back-end correction that
  // also tilts (a loop's weakest part) turns the odometry about its vertical only and moves the
  // keyframe to its corrected position. Unlevelled (hold_tilt off), the whole correction is taken.
  struct Result {
    double gap_t, gap_r_deg, tilt_deg;  // published against the expected pose; its tilt against the raw odometry's
    uint64_t levelled;
  };
  auto run = [](bool hold) {
    Drive d(8.0, 0.3, 20.0);
    auto imu = noiseless_imu(d, 19.5, 5);
    FrontendCore core(params_with(&FrontendParams::correction_holds_tilt, hold));
    ImuFeed feed{d, imu, core};
    Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();  // the back-end: keyframe at offset * raw
    offset.translation() = Eigen::Vector3d(0.5, -0.3, 0.4);
    offset.linear() = (Eigen::AngleAxisd(4.0 * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                       Eigen::AngleAxisd(3.0 * M_PI / 180, Eigen::Vector3d::UnitY()))
                          .toRotationMatrix();
    std::optional<Eigen::Isometry3d> kf_raw;
    for (int k = 0; k < 180; ++k) {
      feed.scan(k);
      if (!kf_raw && k >= 80 && feed.last.keyframe) {
        kf_raw = feed.last.keyframe->T_odom_keyframe;
        EXPECT_TRUE(core.set_correction(feed.last.keyframe->id, offset * *kf_raw, Eigen::Isometry3d::Identity()));
      }
    }
    EXPECT_TRUE(kf_raw.has_value());
    // What the published pose converges to: C * raw, with C the correction as taken in.
    Eigen::Isometry3d C = offset;
    if (hold) {
      C.linear() = Eigen::AngleAxisd(4.0 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      C.translation() = (offset * *kf_raw).translation() - C.linear() * kf_raw->translation();
    }
    const Eigen::Isometry3d gap = (C * feed.last.T_odom_raw).inverse() * feed.last.T_odom_base;
    const Eigen::Vector3d up_pub = feed.last.T_odom_base.rotation().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d up_raw = feed.last.T_odom_raw.rotation().transpose() * Eigen::Vector3d::UnitZ();
    return Result{gap.translation().norm(), geometry::rotation_angle(gap.rotation()) * 180 / M_PI,
                  std::acos(std::clamp(up_pub.dot(up_raw), -1.0, 1.0)) * 180 / M_PI, core.stats().corrections_levelled};
  };
  const Result held = run(true), whole = run(false);
  std::printf("held: gap %.4f m %.4f deg, tilt %.3f deg; whole: gap %.4f m %.4f deg, tilt %.3f deg\n", held.gap_t,
              held.gap_r_deg, held.tilt_deg, whole.gap_t, whole.gap_r_deg, whole.tilt_deg);
  EXPECT_EQ(held.levelled, 1u);
  EXPECT_LT(held.gap_t, 0.01);
  EXPECT_LT(held.gap_r_deg, 0.01);
  EXPECT_LT(held.tilt_deg, 0.01) << "the published roll and pitch stay the odometry's";
  EXPECT_EQ(whole.levelled, 0u);
  EXPECT_LT(whole.gap_t, 0.01);
  EXPECT_LT(whole.gap_r_deg, 0.01);
  EXPECT_NEAR(whole.tilt_deg, 3.0, 0.2) << "unlevelled corrections tilt the odometry";
}

TEST(Frontend, TheImuWindowPredictsTheSweepsAndFindsTheGyroBias) {
  Drive d(10.0, 0.5, 14.0);
  const Eigen::Vector3d bg(0.004, -0.003, 0.006), ba(0.05, -0.03, 0.04);
  auto imu = noiseless_imu(d, 13.0, 9);
  for (auto& m : imu) {
    m.gyro += bg;
    m.accel += ba;
  }
  FrontendCore core(FrontendParams{});
  ImuFeed feed{d, imu, core};
  const Eigen::Isometry3d& T0 = feed.T0;
  const double& worst = feed.worst;
  for (int k = 0; k < 80; ++k) feed.scan(k);
  const FrontendStats& st = core.stats();
  ASSERT_TRUE(core.imu_state().has_value());
  ASSERT_TRUE(core.gravity().has_value());
  const Eigen::Vector3d g_true = T0.rotation().transpose() * sim::kGravity;
  const double g_angle = std::acos(std::clamp(core.gravity()->normalized().dot(g_true.normalized()), -1.0, 1.0));
  std::printf(
      "%llu of 80 sweeps predicted by the IMU window; gyro bias error %.5f rad/s; gravity off by %.2f deg; "
      "worst position error over 100 m %.3f m\n",
      static_cast<unsigned long long>(st.imu_predictions), (core.imu_state()->bg - bg).norm(), g_angle * 180 / M_PI,
      worst);
  // The window aligns gravity over its first 30 sweeps (3 s), then predicts every sweep.
  EXPECT_GE(st.imu_predictions, 48u);
  EXPECT_EQ(st.imu_predictions_rejected, 0u);
  EXPECT_EQ(st.imu_window_restarts, 0u);
  EXPECT_LT((core.imu_state()->bg - bg).norm(), 1.5e-3);
  EXPECT_LT(g_angle, 1.5 * M_PI / 180);
  EXPECT_LT(worst, 0.25);
  EXPECT_EQ(st.registration_failures, 0u);
  // An IMU gap (the node clears the history; nothing between 8.1 and 8.15 s): the interval before
  // sweep 80 is not covered, the window restarts there and predicts again two sweeps on.
  core.clear_imu();
  feed.next = 0;
  while (feed.next < imu.size() && imu[feed.next].t <= 8.15) ++feed.next;
  const uint64_t before = st.imu_predictions;
  for (int k = 80; k < 90; ++k) feed.scan(k);
  EXPECT_EQ(st.imu_window_restarts, 1u);
  EXPECT_GE(st.imu_predictions, before + 7);
  EXPECT_EQ(st.registration_failures, 0u);
}

TEST(Frontend, LevellingWithGravityHoldsTheTiltOfAMiscalibratedLidar) {
  // A VLP-16 whose beams fire off their nominal elevations (0.3 deg sigma, one draw per beam) sees
  // flat ground as a shallow cone, and scan-to-map registration tilts slowly. The IMU window's
  // gravity turns with that tilt; levelled, the odometry keeps its roll, pitch and height. Measured
  // frame-free, as the motion from sweep 80 (after the reference is taken) to the last, in the body
  // frame at sweep 80: its tilt error and its height error.
  struct Result {
    double tilt_deg, dz_m, level_deg;
  };
  auto run = [](bool level) {
    Drive d(10.0, 0.5, 40.0);
    std::mt19937_64 cal(17);
    std::normal_distribution<double> err(0.0, 0.3);
    for (size_t b = 0; b < d.lidar.elevations_deg.size(); ++b) d.lidar.elevation_error_deg.push_back(err(cal));
    auto imu = noiseless_imu(d, 39.5, 9);
    FrontendCore core(params_with(&FrontendParams::level_with_gravity, level));
    ImuFeed feed{d, imu, core};
    const int from = 80, sweeps = 380;
    Eigen::Isometry3d odom_from = Eigen::Isometry3d::Identity();
    for (int k = 0; k < sweeps; ++k) {
      feed.scan(k);
      if (k == from) odom_from = feed.last.T_odom_raw;
    }
    const Eigen::Isometry3d truth = d.traj.pose(0.2 + 0.1 * from).inverse() * d.traj.pose(0.2 + 0.1 * (sweeps - 1));
    const Eigen::Isometry3d odom = odom_from.inverse() * feed.last.T_odom_raw;
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();  // the body's, on a flat road
    const Eigen::Vector3d up_end_true = truth.rotation().transpose() * up;
    const Eigen::Vector3d up_end_odom = odom.rotation().transpose() * up;
    const double tilt = std::acos(std::clamp(up_end_true.dot(up_end_odom), -1.0, 1.0)) * 180 / M_PI;
    return Result{tilt, odom.translation().z() - truth.translation().z(), core.stats().level_deg};
  };
  const Result raw = run(false), levelled = run(true);
  std::printf("over 300 m: tilt off by %.2f deg, height by %.2f m; levelled (turned by %.2f deg): %.2f deg, %.2f m\n",
              raw.tilt_deg, raw.dz_m, levelled.level_deg, levelled.tilt_deg, levelled.dz_m);
  EXPECT_EQ(raw.level_deg, 0.0);
  EXPECT_GT(raw.tilt_deg, 0.5);
  EXPECT_GT(levelled.level_deg, 0.5);
  EXPECT_LT(levelled.tilt_deg, 0.25 * raw.tilt_deg);
  EXPECT_LT(std::abs(levelled.dz_m), 0.25 * std::abs(raw.dz_m));
}

TEST(Frontend, DeskewingWithTheImusWholeMotionFollowsTheDrive) {
  Drive d(10.0, 0.5, 9.0);
  auto imu = noiseless_imu(d, 8.5, 9);
  FrontendCore core(params_with(&FrontendParams::imu_deskew, true));
  ImuFeed feed{d, imu, core};
  for (int k = 0; k < 75; ++k) feed.scan(k);
  std::printf("IMU-deskewed: %llu sweeps predicted, worst position error over 80 m %.3f m\n",
              static_cast<unsigned long long>(core.stats().imu_predictions), feed.worst);
  EXPECT_GE(core.stats().imu_predictions, 40u);
  EXPECT_EQ(core.stats().registration_failures, 0u);
  EXPECT_LT(feed.worst, 0.25);
}

// A hand-held LiDAR without IMU at 2 Hz in the simulated world: standing still, then turning by
// up to 55 deg between two sweeps while walking. The sweeps carry no per-point times (taken at one
// pose, as a motion-compensated sweep is).
struct HandHeld {
  Drive d{8.0, 0.0, 4.0};  // only its world (a road with buildings, 40 m) is used
  std::vector<Eigen::Isometry3d> poses;
  HandHeld() {
    d.lidar = sim::LidarModel::vlp16();
    // Yaw between consecutive sweeps [deg]: still, then sharp turns both ways while walking 0.4 m a sweep.
    const std::vector<double> yaw = {0, 0, 0, 0, 0, 0, 5, 12, 35, -20, -45, 10, 55, 25, -30, 8, 40, -15, 0};
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(12, 0, 1.73);
    for (size_t k = 0; k < yaw.size(); ++k) {
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      step.linear() = Eigen::AngleAxisd(yaw[k] * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
      T = T * step;
      if (k >= 6) T.translation() += Eigen::Vector3d(0.4, 0.0, 0.0);
      poses.push_back(T);
    }
  }
  // Worst position and heading error of the odometry against the truth; the core's stats.
  std::pair<double, double> run(const FrontendParams& p, FrontendStats& stats) {
    FrontendCore core(p);
    double worst_m = 0, worst_rad = 0;
    for (size_t k = 0; k < poses.size(); ++k) {
      std::vector<ScanPoint> pts;
      for (const auto& q : sim::sweep(
               d.world, d.lidar, [&](double) { return poses[k]; }, d.rng)) {
        pts.push_back({Eigen::Vector3f(q.x, q.y, q.z), 0.0F, q.ring});
      }
      const ScanOut o = core.process(static_cast<int64_t>(k) * 500'000'000, pts);
      const Eigen::Isometry3d e = (poses.front().inverse() * poses[k]).inverse() * o.T_odom_raw;
      worst_m = std::max(worst_m, e.translation().norm());
      worst_rad = std::max(worst_rad, geometry::rotation_angle(e.rotation()));
    }
    stats = core.stats();
    return {worst_m, worst_rad};
  }
};

TEST(FrontendRecovery, SharpTurnsBetweenSlowSweepsAreRecovered) {
  HandHeld h;
  FrontendStats with_stats, without_stats;
  const auto [with_m, with_rad] = h.run(FrontendParams{}, with_stats);
  FrontendParams off;
  off.recovery.enabled = false;
  const auto [without_m, without_rad] = h.run(off, without_stats);
  std::printf(
      "hand-held at 2 Hz: worst error %.3f m %.2f deg with recovery (%llu of %llu attempts, %llu global), %.3f m %.2f "
      "deg "
      "without\n",
      with_m, with_rad * 180 / M_PI, static_cast<unsigned long long>(with_stats.recoveries),
      static_cast<unsigned long long>(with_stats.recovery_attempts),
      static_cast<unsigned long long>(with_stats.recoveries_global), without_m, without_rad * 180 / M_PI);
  EXPECT_EQ(with_stats.registration_failures, 0u);
  EXPECT_GT(with_stats.recoveries, 0u);
  EXPECT_LT(with_m, 0.1);
  EXPECT_LT(with_rad, 1.0 * M_PI / 180);
  EXPECT_GT(without_rad, 10.0 * M_PI / 180) << "the turns this test needs: the prediction alone loses them";
}

}  // namespace
}  // namespace cdc::frontend
