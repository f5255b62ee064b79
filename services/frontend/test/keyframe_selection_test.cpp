// Keyframe selection: the first keyframe at once, then one every metre or 0.2 rad; the relative
// odometry and its information from the registrations in between; a held first keyframe goes out
// with the next sweep, its cloud made again; keyframe poses looked up by id.
#include "cdc/frontend/keyframe_selection.hpp"

#include <gtest/gtest.h>

namespace cdc::frontend {
namespace {

Eigen::Isometry3d at(double x, double yaw = 0.0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = x;
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

const std::vector<Eigen::Vector3d> kCloud = {Eigen::Vector3d(5, 0, 0), Eigen::Vector3d(0, 5, 0),
                                             Eigen::Vector3d(0, 0, 5)};

TEST(KeyframeSelection, TheFirstAtOnceThenOneEveryMetreOrTurn) {
  KeyframeSelector kf{FrontendParams{}};  // 1 m, 0.2 rad
  const auto k0 = kf.select(10, at(0.0), kCloud, false);
  ASSERT_TRUE(k0.has_value());
  EXPECT_EQ(k0->id, 0u);
  EXPECT_EQ(k0->stamp_ns, 10);
  EXPECT_TRUE(k0->T_prev.isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_TRUE(k0->information.isApprox(Matrix6d::Identity() * 1e6));
  EXPECT_EQ(k0->cloud.size(), kCloud.size());
  EXPECT_FALSE(kf.select(20, at(0.9), kCloud, false).has_value());
  const auto k1 = kf.select(30, at(1.0), kCloud, false);
  ASSERT_TRUE(k1.has_value());
  EXPECT_EQ(k1->id, 1u);
  EXPECT_TRUE(k1->T_prev.isApprox(at(1.0)));
  EXPECT_FALSE(kf.select(40, at(1.0, 0.15), kCloud, false).has_value());
  const auto k2 = kf.select(50, at(1.0, 0.2), kCloud, false);
  ASSERT_TRUE(k2.has_value());
  EXPECT_EQ(k2->id, 2u);
  EXPECT_TRUE(k2->T_prev.isApprox(at(0.0, 0.2)));
  EXPECT_EQ(kf.count(), 3u);
}

TEST(KeyframeSelection, TheInformationIsTheInverseOfTheRegistrationsCovariances) {
  FrontendParams p;
  KeyframeSelector kf(p);
  kf.select(0, at(0.0), kCloud, false);
  odometry::RegistrationResult reg;
  reg.correspondences = 500;
  reg.hessian = Matrix6d::Identity() * 50.0;
  reg.hessian(5, 5) = 5.0;  // a weaker yaw
  kf.add_registration(reg);
  kf.add_registration(reg);
  odometry::RegistrationResult none = reg;
  none.correspondences = 0;
  none.hessian = Matrix6d::Identity();
  kf.add_registration(none);  // no correspondences: adds nothing
  const auto k = kf.select(10, at(1.5), kCloud, false);
  ASSERT_TRUE(k.has_value());
  // Two registrations: half the information of one, scaled.
  const Matrix6d expected = reg.hessian * p.keyframe_information_scale / 2.0;
  EXPECT_TRUE(k->information.isApprox(expected, 1e-4)) << k->information;
  // The next keyframe starts afresh: with no registration in between, only the regularisation.
  const auto k2 = kf.select(20, at(3.0), kCloud, false);
  ASSERT_TRUE(k2.has_value());
  EXPECT_GT(k2->information.diagonal().minCoeff(), 1e7);
}

TEST(KeyframeSelection, AHeldFirstKeyframeGoesOutWithTheNextSweep) {
  KeyframeSelector kf{FrontendParams{}};
  EXPECT_FALSE(kf.select(10, at(0.0), kCloud, true).has_value());
  EXPECT_TRUE(kf.holding());
  // Its sweep deskewed anew: the cloud is made again.
  kf.redeskew_held({Eigen::Vector3d(7, 0, 0)});
  const auto held = kf.select(20, at(5.0), kCloud, false);
  ASSERT_TRUE(held.has_value());
  EXPECT_FALSE(kf.holding());
  EXPECT_EQ(held->id, 0u);
  EXPECT_EQ(held->stamp_ns, 10);
  ASSERT_EQ(held->cloud.size(), 1u);
  EXPECT_TRUE(held->cloud[0].isApprox(Eigen::Vector3f(7, 0, 0)));
  // That sweep cut none; the next one is measured from the held keyframe.
  const auto next = kf.select(30, at(5.0), kCloud, false);
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->id, 1u);
  EXPECT_TRUE(next->T_prev.isApprox(at(5.0)));
}

TEST(KeyframeSelection, CloudsAreVoxelFilteredAndPosesFoundById) {
  FrontendParams p;
  p.keyframe_voxel_m = 1.0;
  KeyframeSelector kf(p);
  std::vector<Eigen::Vector3d> dense;
  for (int i = 0; i < 1000; ++i) dense.emplace_back(10.2 + 0.0005 * i, 0.5, 0.5);  // within one voxel
  const auto k = kf.select(0, at(2.0), dense, false);
  ASSERT_TRUE(k.has_value());
  EXPECT_EQ(k->cloud.size(), 1u);
  ASSERT_TRUE(kf.pose_of(0).has_value());
  EXPECT_TRUE(kf.pose_of(0)->isApprox(at(2.0)));
  EXPECT_FALSE(kf.pose_of(1).has_value());
}

}  // namespace
}  // namespace cdc::frontend
