// The front-end core on simulated sweeps with real motion distortion: deskewing undoes the
// motion, the odometry follows the truth, and a 2 m / 5 deg back-end correction is taken in
// smoothly (every per-scan change bounded by the fusion thresholds) until it is reached. With a
// biased IMU, the sliding window predicts the sweeps and finds the gyro bias.
#include "cdc/frontend/frontend_core.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/voxel_map.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/trajectory.hpp"
#include "cdc/sim/world.hpp"

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <random>

namespace cdc::frontend {
namespace {

// A drive from rest up to `speed` (in 2 s) along a road that winds at up to `yaw_rate`.
struct Drive {
  sim::SplineTrajectory traj;
  sim::World world;
  sim::LidarModel lidar = sim::LidarModel::vlp16();
  std::mt19937_64 rng{2};
  Drive(double speed, double yaw_rate, double duration) {
    std::vector<Eigen::Isometry3d> controls;
    std::vector<Eigen::Vector3d> path;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().z() = 1.73;
    for (int i = 0; i < static_cast<int>(duration * 10) + 40; ++i) {
      controls.push_back(T);
      path.push_back(T.translation());
      Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
      step.translation().x() = speed * 0.1 * std::min(1.0, i / 20.0);
      step.linear() = Eigen::AngleAxisd(yaw_rate * 0.1 * std::sin(0.05 * i), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      T = T * step;
    }
    traj = sim::SplineTrajectory(controls, 0.0, 0.1);
    sim::WorldOptions wo;
    wo.seed = 12;
    wo.spacing_m = 8;
    world = sim::World::generate({path}, wo);
  }
  std::vector<ScanPoint> sweep(double t0) {
    std::vector<ScanPoint> out;
    for (const auto& p : sim::sweep(world, lidar, [&](double t) { return traj.pose(t0 + t); }, rng)) {
      out.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
    }
    return out;
  }
};

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

double run_error(Drive& d, bool deskew, int scans) {
  FrontendParams p;
  p.deskew = deskew;
  FrontendCore core(p);
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

// Fraction of `cloud`'s points with a point of `reference` within `tol` metres (a hash grid of `tol` cells).
double fraction_near(const std::vector<Eigen::Vector3f>& cloud, const std::vector<Eigen::Vector3d>& reference, double tol) {
  auto key = [tol](const Eigen::Vector3d& p) {
    return std::array<long, 3>{std::lround(std::floor(p.x() / tol)), std::lround(std::floor(p.y() / tol)),
                               std::lround(std::floor(p.z() / tol))};
  };
  std::map<std::array<long, 3>, std::vector<Eigen::Vector3d>> grid;
  for (const auto& r : reference) grid[key(r)].push_back(r);
  size_t near = 0;
  for (const auto& p : cloud) {
    const Eigen::Vector3d q = p.cast<double>();
    const auto k = key(q);
    bool found = false;
    for (long dx = -1; dx <= 1 && !found; ++dx) {
      for (long dy = -1; dy <= 1 && !found; ++dy) {
        for (long dz = -1; dz <= 1 && !found; ++dz) {
          const auto it = grid.find({k[0] + dx, k[1] + dy, k[2] + dz});
          if (it == grid.end()) continue;
          for (const auto& r : it->second) found = found || (r - q).squaredNorm() <= tol * tol;
        }
      }
    }
    near += found ? 1 : 0;
  }
  return cloud.empty() ? 0.0 : static_cast<double>(near) / static_cast<double>(cloud.size());
}

// A robot that starts its odometry at speed (a robot of a split KITTI drive): its first sweep's motion
// is unknown when it is taken, so its keyframe goes out with the second sweep, deskewed by the motion
// that sweep tells (sent at once, its cloud was smeared by the metre the robot drove during the sweep,
// and loops verified against it were off by half a metre on simulated KITTI 09).
TEST(Frontend, TheFirstKeyframeOfARobotStartingAtSpeedIsDeskewed) {
  Drive d(10.0, 0.3, 8.0);
  FrontendParams params;
  params.keyframe_voxel_m = 0.005;  // (about) every point kept, so that points can be compared one by one
  FrontendCore core(params);
  const double t0 = 3.0;  // at full speed
  const Eigen::Isometry3d start = d.traj.pose(t0);
  const std::vector<ScanPoint> first = d.sweep(t0);
  const ScanOut o0 = core.process(static_cast<int64_t>(t0 * 1e9), first);
  EXPECT_FALSE(o0.keyframe.has_value());  // held until the motion is known
  const ScanOut o1 = core.process(static_cast<int64_t>((t0 + 0.1) * 1e9), d.sweep(t0 + 0.1));
  ASSERT_TRUE(o1.keyframe.has_value());
  const KeyframeOut& kf = *o1.keyframe;
  EXPECT_EQ(kf.id, 0u);
  EXPECT_EQ(kf.stamp_ns, static_cast<int64_t>(t0 * 1e9));
  EXPECT_TRUE(kf.T_odom_keyframe.isApprox(Eigen::Isometry3d::Identity(), 1e-9));
  // The first sweep deskewed with the true motion into the sensor frame at its start, and as measured.
  std::vector<Eigen::Vector3d> truth;
  std::vector<Eigen::Vector3f> raw;
  for (const auto& p : first) {
    truth.push_back(start.inverse() * d.traj.pose(t0 + p.time_offset) * p.p.cast<double>());
    raw.push_back(p.p);
  }
  const double deskewed = fraction_near(kf.cloud, truth, 0.03), smeared = fraction_near(raw, truth, 0.03);
  std::printf("first keyframe: %.2f of its points within 3 cm of the truly deskewed sweep (as measured: %.2f)\n",
              deskewed, smeared);
  EXPECT_GT(deskewed, 0.9);
  EXPECT_LT(smeared, 0.5);  // the comparison can tell a smeared cloud
  // The next keyframe is measured from the first.
  std::optional<KeyframeOut> next;
  for (int k = 2; k < 10 && !next; ++k) next = core.process(static_cast<int64_t>((t0 + 0.1 * k) * 1e9), d.sweep(t0 + 0.1 * k)).keyframe;
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->id, 1u);
  EXPECT_TRUE(next->T_prev.isApprox(next->T_odom_keyframe, 1e-9));
}

TEST(Frontend, KeyframesCarryRelativeOdometryWithInformation) {
  Drive d(5.0, 0.3, 6.0);
  FrontendCore core(FrontendParams{});
  std::vector<KeyframeOut> kfs;
  for (int k = 0; k < 40; ++k) {
    const double t = 0.2 + 0.1 * k;
    auto o = core.process(static_cast<int64_t>(t * 1e9), d.sweep(t));
    if (o.keyframe) kfs.push_back(std::move(*o.keyframe));
  }
  double travelled = 0;
  for (int k = 1; k < 40; ++k) travelled += (d.traj.pose(0.2 + 0.1 * k).translation() - d.traj.pose(0.1 + 0.1 * k).translation()).norm();
  // A keyframe every metre (the first at the start), none closer than a metre.
  EXPECT_GE(kfs.size(), static_cast<size_t>(travelled * 0.8));
  EXPECT_LE(kfs.size(), static_cast<size_t>(travelled) + 1);
  for (size_t i = 1; i < kfs.size(); ++i) {
    EXPECT_EQ(kfs[i].id, i);
    const Eigen::Isometry3d chained = kfs[i - 1].T_odom_keyframe * kfs[i].T_prev;
    EXPECT_LT((chained.inverse() * kfs[i].T_odom_keyframe).translation().norm(), 1e-9);
    EXPECT_GE(kfs[i].T_prev.translation().norm(), 1.0 - 1e-9);
    Eigen::SelfAdjointEigenSolver<Matrix6d> es(kfs[i].information);
    EXPECT_GT(es.eigenvalues().minCoeff(), 0.0) << "information not positive definite";
    EXPECT_GT(kfs[i].cloud.size(), 500u);
  }
  // The information is not more confident than the odometry is good: the keyframes' relative-pose
  // errors against the truth, whitened by it, stay below one per degree of freedom on average.
  double chi2 = 0;
  for (size_t i = 1; i < kfs.size(); ++i) {
    const Eigen::Isometry3d truth = d.traj.pose(static_cast<double>(kfs[i - 1].stamp_ns) * 1e-9).inverse() *
                                    d.traj.pose(static_cast<double>(kfs[i].stamp_ns) * 1e-9);
    const Eigen::Isometry3d e = truth.inverse() * kfs[i].T_prev;
    Eigen::Matrix<double, 6, 1> r;
    r << e.translation(), Eigen::AngleAxisd(e.rotation()).angle() * Eigen::AngleAxisd(e.rotation()).axis();
    chi2 += r.dot(kfs[i].information * r);
  }
  const double per_dof = chi2 / (6.0 * static_cast<double>(kfs.size() - 1));
  std::printf("keyframe odometry: whitened squared error %.3f per degree of freedom\n", per_dof);
  EXPECT_LT(per_dof, 1.0);
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
      ASSERT_TRUE(core.set_correction(o.keyframe->id, offset * o.keyframe->T_odom_keyframe, Eigen::Isometry3d::Identity()));
    } else if (k > 0) {
      // Beyond the odometry's own increment, the published pose moves by at most the thresholds.
      const Eigen::Isometry3d expected = last_pub * (last_raw.inverse() * o.T_odom_raw);
      const Eigen::Isometry3d step = expected.inverse() * o.T_odom_base;
      worst_step_t = std::max(worst_step_t, step.translation().norm());
      worst_step_r = std::max(worst_step_r, geometry::rotation_angle(step.rotation()));
    }
    if (corrected_kf && o.T_world_base) {
      const Eigen::Isometry3d gap = (offset * o.T_odom_raw).inverse() * o.T_odom_base;
      if (reached_at < 0 && gap.translation().norm() < 0.01 && geometry::rotation_angle(gap.rotation()) < 1e-3) reached_at = k;
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
    auto imu = sim::simulate_imu(d.traj, Eigen::Isometry3d::Identity(), 0.0, 19.5, 200.0, sim::ImuNoise{}, 5);
    FrontendParams p;
    p.correction_holds_tilt = hold;
    FrontendCore core(p);
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
  auto imu = sim::simulate_imu(d.traj, Eigen::Isometry3d::Identity(), 0.0, 13.0, 200.0, sim::ImuNoise{}, 9);
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
  std::printf("%llu of 80 sweeps predicted by the IMU window; gyro bias error %.5f rad/s; gravity off by %.2f deg; "
              "worst position error over 100 m %.3f m\n",
              static_cast<unsigned long long>(st.imu_predictions), (core.imu_state()->bg - bg).norm(), g_angle * 180 / M_PI, worst);
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
    auto imu = sim::simulate_imu(d.traj, Eigen::Isometry3d::Identity(), 0.0, 39.5, 200.0, sim::ImuNoise{}, 9);
    FrontendParams p;
    p.level_with_gravity = level;
    FrontendCore core(p);
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
  auto imu = sim::simulate_imu(d.traj, Eigen::Isometry3d::Identity(), 0.0, 8.5, 200.0, sim::ImuNoise{}, 9);
  FrontendParams p;
  p.imu_deskew = true;
  FrontendCore core(p);
  ImuFeed feed{d, imu, core};
  for (int k = 0; k < 75; ++k) feed.scan(k);
  std::printf("IMU-deskewed: %llu sweeps predicted, worst position error over 80 m %.3f m\n",
              static_cast<unsigned long long>(core.stats().imu_predictions), feed.worst);
  EXPECT_GE(core.stats().imu_predictions, 40u);
  EXPECT_EQ(core.stats().registration_failures, 0u);
  EXPECT_LT(feed.worst, 0.25);
}

TEST(FrontendCore, TheImusMotionOverASweepFollowsAnAcceleratingTurningDrive) {
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
  T_lidar_imu.linear() = Eigen::AngleAxisd(2.0 * M_PI / 180, Eigen::Vector3d(0.3, 0.5, 1).normalized()).toRotationMatrix();
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
    const Eigen::Vector3d v_imu = traj.velocity(t0) + L0.rotation() * traj.angular_velocity(t0).cross(T_lidar_imu.translation());
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
      worst_rot_only = std::max(worst_rot_only, geometry::rotation_angle(truth.rotation().transpose() * rot_only.rotation()));
      EXPECT_LT(rot_only.translation().norm(), 1e-12);
    }
  }
  std::printf("within a sweep: IMU %.2f mm, constant velocity %.2f mm; rotation %.4f deg\n", worst_imu * 1e3, worst_cv * 1e3,
              worst_rot * 180 / M_PI);
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

TEST(FrontendCore, RegistrationsFarFromThePredictionAreImplausible) {
  FrontendParams p;  // max_gate_m 2 m, max_jump_rad 0.35
  Eigen::Isometry3d prediction = Eigen::Isometry3d::Identity();
  prediction.translation() = Eigen::Vector3d(10, 0, 1.7);
  Eigen::Isometry3d reg = prediction;
  reg.translation() += Eigen::Vector3d(0.5, 0.2, -0.1);
  EXPECT_TRUE(plausible_registration(prediction, reg, p));
  reg.translation() = prediction.translation() + Eigen::Vector3d(0.4, 0, -4.8);  // slid 4.8 m down
  EXPECT_FALSE(plausible_registration(prediction, reg, p));
  reg = prediction * Eigen::Isometry3d(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  EXPECT_FALSE(plausible_registration(prediction, reg, p));
  reg = prediction * Eigen::Isometry3d(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(plausible_registration(prediction, reg, p));
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
      for (const auto& q : sim::sweep(d.world, d.lidar, [&](double) { return poses[k]; }, d.rng)) {
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
  std::printf("hand-held at 2 Hz: worst error %.3f m %.2f deg with recovery (%llu of %llu attempts, %llu global), %.3f m %.2f deg "
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

// A sweep whose points all carry time 0 has no per-point times: it is taken as it is whether
// deskewing is on or off (there is nothing to deskew it with), and the first keyframe goes out at once.
TEST(FrontendRecovery, ASweepWithoutPerPointTimesIsTakenAsItIs) {
  Drive d(8.0, 0.3, 3.0);
  FrontendParams on, off;
  off.deskew = false;
  FrontendCore a(on), b(off);
  for (int k = 0; k < 12; ++k) {
    const double t = 0.2 + 0.1 * k;
    std::vector<ScanPoint> pts = d.sweep(t);
    for (auto& p : pts) p.time_offset = 0.0F;
    const ScanOut oa = a.process(static_cast<int64_t>(t * 1e9), pts), ob = b.process(static_cast<int64_t>(t * 1e9), pts);
    EXPECT_TRUE(oa.T_odom_raw.isApprox(ob.T_odom_raw, 1e-12)) << "sweep " << k;
    EXPECT_EQ(oa.keyframe.has_value(), ob.keyframe.has_value()) << "sweep " << k;
    if (k == 0) {
      EXPECT_TRUE(oa.keyframe.has_value()) << "nothing to wait for: the first keyframe goes out with its sweep";
    }
  }
}

}  // namespace
}  // namespace cdc::frontend
