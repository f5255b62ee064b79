// The clouds of the robot's own keyframes and its own loops, kept for re-sending.
#include "../src/own_records.hpp"

#include "cdc/dds/convert.hpp"

#include <gtest/gtest.h>

namespace cdc::peer {
namespace {

// Keeps the cloud of keyframe `id` from a cloud that is gone once it is kept (as a reader's samples are).
void keep_cloud(OwnRecords& records, uint32_t id, size_t points) {
  std::vector<cdc_msg_PointXYZI> cloud(points, cdc_msg_PointXYZI{static_cast<float>(id), 2.0f, 3.0f, 0.0f});
  cdc_msg_Keyframe m{};
  m.robot_id = 1;
  m.keyframe_id = id;
  m.point_count = static_cast<uint32_t>(points);
  dds::borrow(m.cloud, cloud);
  records.keep_cloud(m);
  cloud.assign(points, cdc_msg_PointXYZI{-1.0f, -1.0f, -1.0f, -1.0f});
}

// The core decides which keyframe an id names; the first cloud kept under an id stays.
TEST(OwnRecords, CloudsAreKeptByIdAndNeverReplaced) {
  OwnRecords records;
  keep_cloud(records, 3, 5);
  keep_cloud(records, 4, 2);
  EXPECT_EQ(records.clouds(), 2u);
  const std::vector<cdc_msg_PointXYZI>* c = records.cloud(3);
  ASSERT_NE(c, nullptr);
  ASSERT_EQ(c->size(), 5u);
  EXPECT_FLOAT_EQ((*c)[4].x, 3.0f);
  keep_cloud(records, 3, 7);
  EXPECT_EQ(records.clouds(), 2u);
  EXPECT_EQ(records.cloud(3)->size(), 5u);
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
