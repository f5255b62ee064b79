#include "cdc/geometry/se3.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace cdc::geometry {
namespace {

Eigen::Isometry3d random_pose(std::mt19937& rng, double max_angle = M_PI - 1e-3) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> a(0.0, max_angle);
  Eigen::Vector3d axis(u(rng), u(rng), u(rng));
  axis.normalize();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(a(rng), axis).toRotationMatrix();
  T.translation() = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 10.0;
  return T;
}

TEST(Se3, So3ExpLogRoundTrip) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 200; ++k) {
    Eigen::Vector3d phi(u(rng), u(rng), u(rng));
    phi *= (M_PI - 1e-3) * std::abs(u(rng)) / phi.norm();
    EXPECT_LT((so3_log(so3_exp(phi)) - phi).norm(), 1e-9) << phi.transpose();
  }
  // Tiny angles take the series branch and stay exact to first order.
  const Eigen::Vector3d tiny(1e-12, -2e-12, 3e-12);
  EXPECT_LT((so3_log(so3_exp(tiny)) - tiny).norm(), 1e-18);
}

TEST(Se3, Se3ExpLogRoundTrip) {
  std::mt19937 rng(2);
  for (int k = 0; k < 200; ++k) {
    const Eigen::Isometry3d T = random_pose(rng);
    const Eigen::Isometry3d back = se3_exp(se3_log(T));
    EXPECT_LT((back.matrix() - T.matrix()).norm(), 1e-9);
  }
}

TEST(Se3, Se3ExpOfPureTranslationAndRotation) {
  Vector6d xi = Vector6d::Zero();
  xi << 1, 2, 3, 0, 0, 0;
  EXPECT_LT((se3_exp(xi).translation() - Eigen::Vector3d(1, 2, 3)).norm(), 1e-15);
  xi << 0, 0, 0, 0, 0, M_PI / 2;
  const Eigen::Isometry3d T = se3_exp(xi);
  EXPECT_LT((T.rotation() * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-12);
}

TEST(Se3, LeftJacobianInverse) {
  const Eigen::Vector3d phi(0.3, -0.7, 1.1);
  EXPECT_LT((so3_left_jacobian(phi) * so3_left_jacobian_inverse(phi) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

TEST(Se3, ComposeInverse) {
  std::mt19937 rng(3);
  const Eigen::Isometry3d A = random_pose(rng);
  const Eigen::Isometry3d B = random_pose(rng);
  const Eigen::Isometry3d AB = A * B;
  EXPECT_LT(((A.inverse() * AB).matrix() - B.matrix()).norm(), 1e-9);
  EXPECT_LT(((AB * B.inverse()).matrix() - A.matrix()).norm(), 1e-9);
}

TEST(Se3, RpyRoundTripAndConvention) {
  const double roll = 0.1, pitch = -0.4, yaw = 2.5;
  const Eigen::Matrix3d R = from_rpy(roll, pitch, yaw);
  const Eigen::Vector3d rpy = to_rpy(R);
  EXPECT_NEAR(rpy.x(), roll, 1e-12);
  EXPECT_NEAR(rpy.y(), pitch, 1e-12);
  EXPECT_NEAR(rpy.z(), yaw, 1e-12);
  // Pure yaw turns x into the direction of the yaw angle.
  const Eigen::Vector3d x = from_rpy(0, 0, M_PI / 2) * Eigen::Vector3d::UnitX();
  EXPECT_LT((x - Eigen::Vector3d::UnitY()).norm(), 1e-12);
}

TEST(Se3, SlerpEndpointsAndMidpoint) {
  const Eigen::Quaterniond a(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()));
  const Eigen::Quaterniond b(Eigen::AngleAxisd(1.4, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(slerp(a, b, 0.0).angularDistance(a), 1e-12);
  EXPECT_LT(slerp(a, b, 1.0).angularDistance(b), 1e-12);
  const Eigen::Quaterniond mid(Eigen::AngleAxisd(0.8, Eigen::Vector3d::UnitZ()));
  EXPECT_LT(slerp(a, b, 0.5).angularDistance(mid), 1e-12);
  // Constant angular rate: a quarter of the way is a quarter of the angle.
  EXPECT_NEAR(slerp(a, b, 0.25).angularDistance(a), 0.3, 1e-12);
}

TEST(Se3, SlerpTakesTheShortestArc) {
  const Eigen::Quaterniond a(Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitX()));
  Eigen::Quaterniond b(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitX()));
  b.coeffs() = -b.coeffs();  // same rotation, opposite hemisphere
  const Eigen::Quaterniond mid(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()));
  EXPECT_LT(slerp(a, b, 0.5).angularDistance(mid), 1e-12);
}

TEST(Se3, InterpolatePose) {
  Eigen::Isometry3d a = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.translation() = Eigen::Vector3d(4, 0, -2);
  b.linear() = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Isometry3d m = interpolate(a, b, 0.25);
  EXPECT_LT((m.translation() - Eigen::Vector3d(1, 0, -0.5)).norm(), 1e-12);
  EXPECT_NEAR(rotation_angle(m.rotation()), 0.25, 1e-12);
  EXPECT_LT((interpolate(a, b, 1.0).matrix() - b.matrix()).norm(), 1e-12);
}

TEST(Se3, RotationAngleAndProjection) {
  EXPECT_NEAR(rotation_angle(Eigen::AngleAxisd(2.0, Eigen::Vector3d::UnitZ()).toRotationMatrix()), 2.0, 1e-12);
  Eigen::Matrix3d R = from_rpy(0.3, 0.2, 0.1);
  Eigen::Matrix3d noisy = R;
  noisy(0, 1) += 1e-4;
  const Eigen::Matrix3d P = project_to_so3(noisy);
  EXPECT_LT((P * P.transpose() - Eigen::Matrix3d::Identity()).norm(), 1e-12);
  EXPECT_NEAR(P.determinant(), 1.0, 1e-12);
  EXPECT_LT((P - R).norm(), 1e-4);
}

TEST(Se3, TwistAboutAnAxisKeepsOnlyTheTurnAboutIt) {
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  // Yaw 0.7 after a tilt of 0.2 about x: the twist about z is the yaw, the swing turns z.
  const Eigen::Quaterniond yaw(Eigen::AngleAxisd(0.7, z)), tilt(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitX()));
  const Eigen::Quaterniond q = tilt * yaw;
  const Eigen::Quaterniond tw = twist_about(q, z);
  EXPECT_NEAR(tw.angularDistance(yaw), 0.0, 1e-12);
  const Eigen::Quaterniond swing = q * tw.conjugate();
  EXPECT_NEAR(swing.angularDistance(tilt), 0.0, 1e-12);
  // A pure tilt has no twist; a pure turn about the axis is its own twist (either sign of q).
  EXPECT_NEAR(twist_about(tilt, z).angularDistance(Eigen::Quaterniond::Identity()), 0.0, 1e-12);
  const Eigen::Quaterniond minus_yaw(-yaw.w(), -yaw.x(), -yaw.y(), -yaw.z());
  EXPECT_NEAR(twist_about(minus_yaw, z).angularDistance(yaw), 0.0, 1e-12);
  // About another axis: the twist about x of the tilt is the tilt.
  EXPECT_NEAR(twist_about(tilt, Eigen::Vector3d::UnitX()).angularDistance(tilt), 0.0, 1e-12);
  // Half a turn about x maps z to -z: no twist about z is defined, identity is returned.
  const Eigen::Quaterniond flip(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()));
  EXPECT_NEAR(twist_about(flip, z).angularDistance(Eigen::Quaterniond::Identity()), 0.0, 1e-12);
}

}  // namespace
}  // namespace cdc::geometry
