// The front-end core on short simulated drives: the first keyframe of a robot starting at speed
// goes out deskewed, keyframes carry relative odometry with an information no more confident than
// the odometry is good, and a sweep without per-point times is taken as it is. The long drives are
// in frontend_core_sim_test.
#include "simulated_drive.hpp"

#include "cdc/frontend/frontend_core.hpp"

#include <gtest/gtest.h>
#include <Eigen/Eigenvalues>

#include <array>
#include <cmath>
#include <cstdio>
#include <map>

namespace cdc::frontend {
namespace {

// Fraction of `cloud`'s points with a point of `reference` within `tol` metres (a hash grid of `tol` cells).
double fraction_near(const std::vector<Eigen::Vector3f>& cloud, const std::vector<Eigen::Vector3d>& reference,
                     double tol) {
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
// that sweep tells (sent at once, its cloud is smeared by the metre the robot drives during the sweep,
// and loops verified against it are off by half a metre on simulated KITTI 09).
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
  for (int k = 2; k < 10 && !next; ++k)
    next = core.process(static_cast<int64_t>((t0 + 0.1 * k) * 1e9), d.sweep(t0 + 0.1 * k)).keyframe;
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->id, 1u);
  EXPECT_TRUE(next->T_prev.isApprox(next->T_odom_keyframe, 1e-9));
}

// The keyframes the core makes of the drive's first n sweeps, 0.1 s apart from 0.2 s.
std::vector<KeyframeOut> drive_keyframes(FrontendCore& core, Drive& d, int n) {
  std::vector<KeyframeOut> kfs;
  for (int k = 0; k < n; ++k) {
    const double t = 0.2 + 0.1 * k;
    auto o = core.process(static_cast<int64_t>(t * 1e9), d.sweep(t));
    if (o.keyframe) kfs.push_back(std::move(*o.keyframe));
  }
  return kfs;
}

TEST(Frontend, KeyframesCarryRelativeOdometryWithInformation) {
  Drive d(5.0, 0.3, 6.0);
  FrontendCore core(FrontendParams{});
  const std::vector<KeyframeOut> kfs = drive_keyframes(core, d, 40);
  double travelled = 0;
  for (int k = 1; k < 40; ++k)
    travelled += (d.traj.pose(0.2 + 0.1 * k).translation() - d.traj.pose(0.1 + 0.1 * k).translation()).norm();
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

// A restarted front-end continues the robot's keyframe sequence: ids after the newest keyframe its
// back-end holds, its odometry frame that keyframe's (its start placed at the keyframe's pose), and a
// first keyframe tied to that keyframe by a weak link; later keyframes chain as usual.
TEST(Frontend, ARestartedFrontEndContinuesTheKeyframeSequence) {
  Drive d(5.0, 0.3, 6.0);
  FrontendCore first(FrontendParams{});
  const std::vector<KeyframeOut> before = drive_keyframes(first, d, 20);
  ASSERT_FALSE(before.empty());
  const KeyframeOut* newest = &before.back();
  ASSERT_GT(newest->id, 0u);
  FrontendParams params;
  FrontendCore restarted(params), fresh(params);  // fresh: the same sweeps in a new sequence
  restarted.continue_sequence(newest->id, newest->T_odom_keyframe);
  const double t0 = 3.0;  // the restart took a second
  std::vector<KeyframeOut> kfs;
  for (int k = 0; k < 20; ++k) {
    const double t = t0 + 0.1 * k;
    const std::vector<ScanPoint> sweep = d.sweep(t);
    const ScanOut o = restarted.process(static_cast<int64_t>(t * 1e9), sweep);
    const ScanOut f = fresh.process(static_cast<int64_t>(t * 1e9), sweep);
    // The odometry frame is the sequence's: this front-end's own odometry, from the newest keyframe's pose.
    EXPECT_TRUE(o.T_odom_raw.isApprox(newest->T_odom_keyframe * f.T_odom_raw, 1e-9)) << "sweep " << k;
    const Eigen::Isometry3d truth = newest->T_odom_keyframe * d.traj.pose(t0).inverse() * d.traj.pose(t);
    EXPECT_LT((truth.inverse() * o.T_odom_raw).translation().norm(), 0.2) << "sweep " << k;
    if (o.keyframe) kfs.push_back(*o.keyframe);
  }
  ASSERT_GE(kfs.size(), 3u);
  EXPECT_EQ(kfs[0].id, newest->id + 1);
  EXPECT_TRUE(kfs[0].T_odom_keyframe.isApprox(newest->T_odom_keyframe, 1e-9));
  EXPECT_TRUE(kfs[0].T_prev.isApprox(Eigen::Isometry3d::Identity(), 1e-9));
  const Matrix6d link = kfs[0].information;
  EXPECT_NEAR(link(0, 0), 1.0 / (params.restart_link_sigma_m * params.restart_link_sigma_m), 1e-9);
  EXPECT_NEAR(link(5, 5), 1.0 / (params.restart_link_sigma_rad * params.restart_link_sigma_rad), 1e-9);
  EXPECT_NEAR((link - Matrix6d(link.diagonal().asDiagonal())).norm(), 0.0, 1e-12);
  for (size_t i = 1; i < kfs.size(); ++i) {
    EXPECT_EQ(kfs[i].id, kfs[0].id + i);
    const Eigen::Isometry3d chained = kfs[i - 1].T_odom_keyframe * kfs[i].T_prev;
    EXPECT_LT((chained.inverse() * kfs[i].T_odom_keyframe).translation().norm(), 1e-9);
    EXPECT_GT(kfs[i].information(0, 0), 10.0 * link(0, 0)) << "measured odometry is not weak";
  }
  EXPECT_EQ(restarted.stats().keyframes, kfs.size());
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
    const ScanOut oa = a.process(static_cast<int64_t>(t * 1e9), pts),
                  ob = b.process(static_cast<int64_t>(t * 1e9), pts);
    EXPECT_TRUE(oa.T_odom_raw.isApprox(ob.T_odom_raw, 1e-12)) << "sweep " << k;
    EXPECT_EQ(oa.keyframe.has_value(), ob.keyframe.has_value()) << "sweep " << k;
    if (k == 0) {
      EXPECT_TRUE(oa.keyframe.has_value()) << "nothing to wait for: the first keyframe goes out with its sweep";
    }
  }
}

}  // namespace
}  // namespace cdc::frontend
