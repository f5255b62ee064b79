// Gravity levelling: off, the pose as it is; until the reference is known, the registered
// increments composed unturned; then a map frame whose gravity tilts steadily is turned back to the
// reference, and without an estimate the levelling rotation stays.
#include "cdc/frontend/gravity_levelling.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cdc::frontend {
namespace {

Eigen::Isometry3d pose(double x, double y, double z, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// Gravity in a map frame tilted by `deg` about x.
Eigen::Vector3d tilted_gravity(double deg) {
  return Eigen::AngleAxisd(deg * M_PI / 180, Eigen::Vector3d::UnitX()) * Eigen::Vector3d(0, 0, -9.81);
}

TEST(GravityLevelling, OffThePoseIsTakenAsItIs) {
  FrontendParams p;
  p.level_with_gravity = false;
  GravityLeveller leveller(p);
  const Eigen::Isometry3d T = pose(3, 1, 0.5, 0.3);
  for (int k = 0; k < 100; ++k) {
    EXPECT_TRUE(leveller.level(T, pose(0, 0, 0, 0), pose(9, 9, 9, 0), tilted_gravity(0.1 * k)).isApprox(T, 0.0));
  }
  EXPECT_FALSE(leveller.reference_known());
  EXPECT_EQ(leveller.max_angle_deg(), 0.0);
}

TEST(GravityLevelling, UntilTheReferenceIsKnownTheIncrementsComposeUnturned) {
  FrontendParams p;  // the reference 30 sweeps after the window first ran
  GravityLeveller leveller(p);
  const Eigen::Isometry3d T_last = pose(1, 0, 0, 0.1), T = pose(2, 0.5, 0.1, 0.2), T_out_last = pose(11, 0, 0, 0.1);
  for (size_t k = 0; k + 1 < p.level_reference_sweeps; ++k) {
    const Eigen::Isometry3d out = leveller.level(T, T_last, T_out_last, tilted_gravity(0.0));
    EXPECT_TRUE(out.linear().isApprox(T.linear()));
    EXPECT_TRUE(out.translation().isApprox(Eigen::Vector3d(12, 0.5, 0.1)));
  }
  EXPECT_FALSE(leveller.reference_known());
  leveller.level(T, T_last, T_out_last, std::nullopt);
  EXPECT_FALSE(leveller.reference_known()) << "sweeps without an estimate do not count";
  leveller.level(T, T_last, T_out_last, tilted_gravity(0.0));
  EXPECT_TRUE(leveller.reference_known());
}

TEST(GravityLevelling, ASteadilyTiltingMapFrameIsTurnedBack) {
  FrontendParams p;
  GravityLeveller leveller(p);
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  for (size_t k = 0; k < p.level_reference_sweeps; ++k) leveller.level(I, I, I, tilted_gravity(0.0));
  ASSERT_TRUE(leveller.reference_known());
  // The map frame tilts by 3 deg over 600 sweeps (a minute at 10 Hz); the estimate is noiseless.
  Eigen::Isometry3d out = I;
  double deg = 0;
  for (int k = 1; k <= 600; ++k) {
    deg = 0.005 * k;
    out = leveller.level(I, I, I, tilted_gravity(deg));
  }
  EXPECT_NEAR(leveller.angle_deg(), deg, 0.05);
  EXPECT_GE(leveller.max_angle_deg(), leveller.angle_deg());
  // The levelled frame sees gravity where the reference had it.
  const Eigen::Vector3d levelled = out.linear() * tilted_gravity(deg).normalized();
  EXPECT_GT(levelled.dot(-Eigen::Vector3d::UnitZ()), std::cos(0.05 * M_PI / 180));
  // Without an estimate the levelling rotation stays.
  const Eigen::Isometry3d held = leveller.level(I, I, I, std::nullopt);
  EXPECT_TRUE(held.linear().isApprox(out.linear(), 1e-12));
}

}  // namespace
}  // namespace cdc::frontend
