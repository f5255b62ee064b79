// The robot's own keyframes and loops kept for re-sending, and the trajectory written at shutdown.
#include "../src/own_records.hpp"

#include "cdc/dds/convert.hpp"

#include <gtest/gtest.h>

namespace cdc::peer {
namespace {

Eigen::Isometry3d at(double x) { return Eigen::Isometry3d(Eigen::Translation3d(x, 0.0, 0.0)); }

// Keeps keyframe `id` at x = id from a cloud that is gone once it is kept (as a reader's samples are).
void keep_keyframe(OwnRecords& records, uint32_t id, size_t points) {
  std::vector<cdc_msg_PointXYZI> cloud(points, cdc_msg_PointXYZI{static_cast<float>(id), 2.0f, 3.0f, 0.0f});
  cdc_msg_Keyframe m{};
  m.robot_id = 1;
  m.keyframe_id = id;
  m.stamp_ns = 1'000'000'000LL * id;
  m.T_odom_keyframe = dds::to_msg(at(static_cast<double>(id)));
  m.point_count = static_cast<uint32_t>(points);
  dds::borrow(m.cloud, cloud);
  records.keep(m);
  cloud.assign(points, cdc_msg_PointXYZI{-1.0f, -1.0f, -1.0f, -1.0f});
}

TEST(OwnRecords, KeyframesKeepTheirCloudsAndAreReplacedById) {
  OwnRecords records;
  keep_keyframe(records, 3, 5);
  keep_keyframe(records, 4, 2);
  EXPECT_EQ(records.keyframes(), 2u);
  const auto k = records.keyframe(3);
  ASSERT_TRUE(k);
  EXPECT_EQ(k->keyframe_id, 3u);
  ASSERT_EQ(k->cloud._length, 5u);
  EXPECT_FLOAT_EQ(k->cloud._buffer[4].x, 3.0f);
  keep_keyframe(records, 3, 7);
  EXPECT_EQ(records.keyframes(), 2u);
  EXPECT_EQ(records.keyframe(3)->cloud._length, 7u);
  EXPECT_FALSE(records.keyframe(5));
}

TEST(OwnRecords, LoopsBySequenceNumber) {
  OwnRecords records;
  cdc_msg_LoopClosure l{};
  l.loop_seq = 2;
  l.keyframe_b = 10;
  records.keep(l);
  l.keyframe_b = 11;
  records.keep(l);
  ASSERT_NE(records.loop(2), nullptr);
  EXPECT_EQ(records.loop(2)->keyframe_b, 11u);
  EXPECT_EQ(records.loop(3), nullptr);
}

TEST(OwnRecords, WorldTrajectoryFollowsTheCorrections) {
  OwnRecords records;
  EXPECT_TRUE(records.world_trajectory().empty());
  for (uint32_t id = 0; id < 3; ++id) keep_keyframe(records, id, 1);
  // Without corrections: the odometry.
  geometry::Trajectory t = records.world_trajectory();
  ASSERT_EQ(t.size(), 3u);
  EXPECT_EQ(t[2].stamp_ns, 2'000'000'000LL);
  EXPECT_NEAR(t[2].pose.translation().x(), 2.0, 1e-12);
  // Keyframe 1 corrected 0.5 m up: keyframe 2 follows it by its odometry, keyframe 0 by the first correction.
  Eigen::Isometry3d up = at(1.0);
  up.translation().z() = 0.5;
  records.corrected(1, up);
  t = records.world_trajectory();
  ASSERT_EQ(t.size(), 3u);
  EXPECT_NEAR(t[1].pose.translation().z(), 0.5, 1e-12);
  EXPECT_NEAR(t[2].pose.translation().x(), 2.0, 1e-12);
  EXPECT_NEAR(t[2].pose.translation().z(), 0.5, 1e-12);
  EXPECT_NEAR(t[0].pose.translation().z(), 0.5, 1e-12);
}

}  // namespace
}  // namespace cdc::peer
