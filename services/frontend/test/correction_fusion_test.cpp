// Correction fusion: without a correction the published pose is the odometry's; a correction is
// approached by at most the fusion thresholds per sweep and then held; levelled, only its turn about
// the vertical is taken and the keyframe moved to its corrected position; the world pose follows
// T_world_robot.
#include "cdc/frontend/correction_fusion.hpp"
#include "cdc/geometry/se3.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace cdc::frontend {
namespace {

Eigen::Isometry3d pose(const Eigen::Vector3d& t, double yaw_deg, double pitch_deg = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = t;
  T.linear() = (Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch_deg * M_PI / 180, Eigen::Vector3d::UnitY()))
                   .toRotationMatrix();
  return T;
}

TEST(CorrectionFusion, WithoutACorrectionThePublishedPoseIsTheOdometry) {
  CorrectionFusion fusion{FrontendParams{}};
  const Eigen::Isometry3d T = pose(Eigen::Vector3d(4, 2, 0), 30);
  const CorrectionFusion::Fused f = fusion.fuse(Eigen::Isometry3d::Identity(), T);
  EXPECT_TRUE(f.T_odom_base.isApprox(T, 0.0));
  EXPECT_FALSE(f.T_world_base.has_value());
  EXPECT_EQ(f.lambda, 1.0);
}

TEST(CorrectionFusion, ACorrectionIsApproachedByAtMostTheThresholdsPerSweep) {
  FrontendParams p;  // 0.10 m, 1 deg per sweep
  CorrectionFusion fusion(p);
  const Eigen::Isometry3d kf = pose(Eigen::Vector3d(10, 0, 0), 0);
  const Eigen::Isometry3d offset = pose(Eigen::Vector3d(2, 0.5, 0), 5);  // corrected = offset * raw
  fusion.fuse(Eigen::Isometry3d::Identity(), kf);
  EXPECT_FALSE(fusion.set_correction(kf, offset * kf, Eigen::Isometry3d::Identity(), false)) << "not levelled";
  Eigen::Isometry3d last = kf;
  int reached = -1;
  double smallest_lambda = 1.0;
  for (int k = 0; k < 60; ++k) {  // standing still at the keyframe
    const CorrectionFusion::Fused f = fusion.fuse(Eigen::Isometry3d::Identity(), kf);
    const Eigen::Isometry3d step = last.inverse() * f.T_odom_base;
    EXPECT_LE(step.translation().norm(), p.fusion.pos_max + 1e-6);
    EXPECT_LE(geometry::rotation_angle(step.rotation()), p.fusion.rot_max + 1e-6);
    smallest_lambda = std::min(smallest_lambda, f.lambda);
    ASSERT_TRUE(f.T_world_base.has_value());
    EXPECT_TRUE(f.T_world_base->isApprox(f.T_odom_base));
    if (reached < 0 && f.T_odom_base.isApprox(offset * kf, 1e-9)) reached = k;
    last = f.T_odom_base;
  }
  EXPECT_LT(smallest_lambda, 1.0) << "the thresholds limited the steps";
  EXPECT_GE(reached, 20) << "2 m take at least 20 sweeps of 0.1 m";
  EXPECT_LT(reached, 40);
}

TEST(CorrectionFusion, LevelledOnlyTheTurnAboutTheVerticalIsTaken) {
  const Eigen::Isometry3d kf = pose(Eigen::Vector3d(10, 0, 0), 20);
  const Eigen::Isometry3d offset = pose(Eigen::Vector3d(0.5, -0.3, 0.4), 4, 3);  // with a 3 deg tilt
  const Eigen::Isometry3d T_world_robot = pose(Eigen::Vector3d(100, 0, 0), 90);
  const Eigen::Isometry3d T_world_kf = T_world_robot * offset * kf;
  auto converged = [&](bool levelled, bool hold_tilt, bool& took_yaw_only) {
    FrontendParams p;
    p.correction_holds_tilt = hold_tilt;
    CorrectionFusion fusion(p);
    fusion.fuse(Eigen::Isometry3d::Identity(), kf);  // published at the keyframe
    took_yaw_only = fusion.set_correction(kf, T_world_kf, T_world_robot, levelled);
    CorrectionFusion::Fused f;
    for (int k = 0; k < 100; ++k) f = fusion.fuse(Eigen::Isometry3d::Identity(), kf);
    EXPECT_TRUE(f.T_world_base->isApprox(T_world_robot * f.T_odom_base));
    return f.T_odom_base;
  };
  bool yaw_only = false;
  const Eigen::Isometry3d held = converged(true, true, yaw_only);
  EXPECT_TRUE(yaw_only);
  // The keyframe at its corrected position, turned by the correction's yaw, its tilt kept.
  EXPECT_LT((held.translation() - (offset * kf).translation()).norm(), 1e-6);
  const Eigen::Vector3d up_held = held.rotation().transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d up_raw = kf.rotation().transpose() * Eigen::Vector3d::UnitZ();
  EXPECT_LT(std::acos(std::clamp(up_held.dot(up_raw), -1.0, 1.0)), 1e-6);
  EXPECT_NEAR(geometry::rotation_angle(kf.rotation().transpose() * held.rotation()), 4.0 * M_PI / 180, 1e-6);
  // Unlevelled, or with the tilt not held, the whole correction.
  for (const auto& [levelled, hold] : {std::pair{false, true}, std::pair{true, false}}) {
    const Eigen::Isometry3d whole = converged(levelled, hold, yaw_only);
    EXPECT_FALSE(yaw_only);
    EXPECT_TRUE(whole.isApprox(offset * kf, 1e-6));
  }
}

}  // namespace
}  // namespace cdc::frontend
