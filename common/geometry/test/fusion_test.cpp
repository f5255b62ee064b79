#include "cdc/geometry/fusion.hpp"
#include "cdc/geometry/se3.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cdc::geometry {
namespace {

Eigen::Isometry3d pose(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0);
  T.linear() = from_rpy(0, 0, yaw);
  return T;
}

TEST(Fusion, SmallDifferencesAreTakenWhole) {
  const FusionResult r = fuse_pose(pose(0, 0, 0), pose(0.05, 0, 0.01), {0.1, 0.02});
  EXPECT_DOUBLE_EQ(r.lambda, 1.0);
  EXPECT_LT((r.fused.matrix() - pose(0.05, 0, 0.01).matrix()).norm(), 1e-12);
}

TEST(Fusion, HandComputedTranslationClipping) {
  // diff_pos = 0.5 > pos_max 0.1 -> posscale 0.2; diff_rot 0.01 < rot_max -> rotscale 1.
  const FusionResult r = fuse_pose(pose(0, 0, 0), pose(0.3, 0.4, 0.01), {0.1, 0.02});
  EXPECT_NEAR(r.diff_pos, 0.5, 1e-12);
  EXPECT_NEAR(r.diff_rot, 0.01, 1e-12);
  EXPECT_NEAR(r.lambda, 0.2, 1e-12);
  EXPECT_NEAR(r.fused.translation().x(), 0.06, 1e-12);
  EXPECT_NEAR(r.fused.translation().y(), 0.08, 1e-12);
  EXPECT_NEAR(rotation_angle(r.fused.rotation()), 0.002, 1e-12);  // slerp at lambda: 0.2 * 0.01
}

TEST(Fusion, RotationSetsLambdaWhenItIsTheTighterLimit) {
  // diff_rot 0.1 > rot_max 0.02 -> rotscale 0.2; diff_pos 0.15 > 0.1 -> posscale 2/3; lambda 0.2.
  const FusionResult r = fuse_pose(pose(1, 1, 0.3), pose(1.15, 1, 0.4), {0.1, 0.02});
  EXPECT_NEAR(r.lambda, 0.2, 1e-12);
  EXPECT_NEAR((r.fused.translation() - Eigen::Vector3d(1.03, 1, 0)).norm(), 0, 1e-12);
  EXPECT_NEAR(to_rpy(r.fused.rotation()).z(), 0.32, 1e-12);
}

TEST(Fusion, SlerpWeightsMatchEquation14) {
  // q = q_a sin((1 - l) th) / sin th + q_b sin(l th) / sin th, th the angle between the quaternions.
  const Eigen::Quaterniond qa(from_rpy(0.1, 0.2, 0.3));
  const Eigen::Quaterniond qb(from_rpy(-0.2, 0.1, 0.9));
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity(), b = Eigen::Isometry3d::Identity();
  a.linear() = qa.toRotationMatrix();
  b.linear() = qb.toRotationMatrix();
  const FusionResult r = fuse_pose(a, b, {1.0, 0.1});
  const double th = std::acos(std::abs(qa.dot(qb)));
  const double l = r.lambda;
  ASSERT_LT(l, 1.0);
  Eigen::Quaterniond expected;
  expected.coeffs() =
      qa.coeffs() * std::sin((1 - l) * th) / std::sin(th) + qb.coeffs() * std::sin(l * th) / std::sin(th);
  EXPECT_LT(Eigen::Quaterniond(r.fused.rotation()).angularDistance(expected), 1e-9);
  EXPECT_NEAR(rotation_angle(a.rotation().transpose() * r.fused.rotation()), 0.1, 1e-9);  // exactly rot_max
}

TEST(Fusion, RepeatedFusionConvergesWithBoundedSteps) {
  const FusionThresholds t{0.1, 0.02};
  Eigen::Isometry3d current = pose(0, 0, 0);
  const Eigen::Isometry3d target = pose(2.0, 0, 5.0 * M_PI / 180.0);
  for (int i = 0; i < 100; ++i) {
    const FusionResult r = fuse_pose(current, target, t);
    EXPECT_LE((r.fused.translation() - current.translation()).norm(), t.pos_max + 1e-12);
    EXPECT_LE(rotation_angle(current.rotation().transpose() * r.fused.rotation()), t.rot_max + 1e-12);
    current = r.fused;
  }
  EXPECT_LT((current.matrix() - target.matrix()).norm(), 1e-9);
}

}  // namespace
}  // namespace cdc::geometry
