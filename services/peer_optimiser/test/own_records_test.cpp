// The clouds of the robot's own keyframes, packed for the radio, and its own loops, kept for re-sending.
#include "../src/own_records.hpp"

#include "cdc/dds/convert.hpp"

#include <gtest/gtest.h>

#include <algorithm>

namespace cdc::peer {
namespace {

// Keeps the cloud of keyframe `id` (points at x = id + i) from a cloud that is gone once it is kept
// (as a reader's samples are).
dds::compact::PackedCloud& keep_cloud(OwnRecords& records, uint32_t id, size_t points) {
  std::vector<cdc_msg_PointXYZI> cloud;
  for (size_t i = 0; i < points; ++i) cloud.push_back({static_cast<float>(id + i), 2.0f, -3.0f, 7.0f});
  cdc_msg_Keyframe m{};
  m.robot_id = 1;
  m.keyframe_id = id;
  m.point_count = static_cast<uint32_t>(points);
  dds::borrow(m.cloud, cloud);
  dds::compact::PackedCloud& kept = records.keep_cloud(m, 0.02f);
  cloud.assign(points, cdc_msg_PointXYZI{-1.0f, -1.0f, -1.0f, -1.0f});
  return kept;
}

// The core decides which keyframe an id names; the first cloud kept under an id stays. The packed
// points come back on the 2 cm grid, in Morton order.
TEST(OwnRecords, CloudsArePackedKeptByIdAndNeverReplaced) {
  OwnRecords records;
  EXPECT_EQ(keep_cloud(records, 3, 5).count, 5u);
  keep_cloud(records, 4, 2);
  EXPECT_EQ(records.clouds(), 2u);
  const dds::compact::PackedCloud* c = records.cloud(3);
  ASSERT_NE(c, nullptr);
  EXPECT_FLOAT_EQ(c->resolution_m, 0.02f);
  std::vector<Eigen::Vector3f> points;
  ASSERT_EQ(dds::compact::unpack_points(c->bytes.data(), c->bytes.size(), c->count, c->resolution_m, points), "");
  ASSERT_EQ(points.size(), 5u);
  std::vector<float> xs;
  for (const Eigen::Vector3f& p : points) {
    EXPECT_NEAR(p.y(), 2.0f, 0.01f);
    EXPECT_NEAR(p.z(), -3.0f, 0.01f);
    xs.push_back(p.x());
  }
  std::sort(xs.begin(), xs.end());
  for (size_t i = 0; i < xs.size(); ++i) EXPECT_NEAR(xs[i], 3.0f + static_cast<float>(i), 0.01f);
  EXPECT_EQ(keep_cloud(records, 3, 7).count, 5u);
  EXPECT_EQ(records.clouds(), 2u);
  EXPECT_EQ(records.cloud(3)->count, 5u);
  EXPECT_EQ(records.cloud(5), nullptr);
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

}  // namespace
}  // namespace cdc::peer
