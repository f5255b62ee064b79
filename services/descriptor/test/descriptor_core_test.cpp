#include "cdc/descriptor/descriptor_core.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cdc::descriptor {
namespace {

// A ring of points around the sensor, a wall 10 m away to one side.
KeyframeCloud keyframe(uint32_t incarnation, uint32_t id) {
  KeyframeCloud k;
  k.robot = 1;
  k.incarnation = incarnation;
  k.keyframe_id = id;
  k.stamp_ns = 1'000'000'000LL * id;
  k.T_odom_keyframe.translation() = Eigen::Vector3d(static_cast<double>(id), 0, 0);
  for (int i = 0; i < 360; ++i) {
    const double a = i * M_PI / 180.0;
    k.points.emplace_back(static_cast<float>(5 * std::cos(a)), static_cast<float>(5 * std::sin(a)), 0.5f);
  }
  for (int i = 0; i < 50; ++i) k.points.emplace_back(10.0f, static_cast<float>(i) * 0.1f, 1.5f);
  return k;
}

TEST(DescriptorCore, DescribesEachKeyframeOnce) {
  DescriptorCore core(lidar::ScanContextParams{}, 256);
  const DescriptorRecord* r = core.describe(keyframe(7, 3));
  ASSERT_NE(r, nullptr);
  EXPECT_EQ(r->keyframe_id, 3u);
  EXPECT_EQ(r->incarnation, 7u);
  EXPECT_EQ(r->pose_hint.translation().x(), 3.0);
  EXPECT_EQ(r->descriptor.rings, 20);
  EXPECT_EQ(r->descriptor.sectors, 60);
  EXPECT_EQ(r->descriptor.cells.size(), 20u * 60u);
  EXPECT_EQ(core.describe(keyframe(7, 3)), nullptr) << "a re-sent keyframe is not described again";
  EXPECT_EQ(core.counters().described, 1u);
  EXPECT_EQ(core.counters().repeated, 1u);
}

TEST(DescriptorCore, ResendsARangeOfTheCurrentIncarnationUpToTheLimit) {
  DescriptorCore core(lidar::ScanContextParams{}, 3);
  for (uint32_t id = 0; id < 10; ++id) ASSERT_NE(core.describe(keyframe(7, id)), nullptr);
  std::vector<uint32_t> ids;
  for (const DescriptorRecord* r : core.resend(2, 8)) ids.push_back(r->keyframe_id);
  EXPECT_EQ(ids, (std::vector<uint32_t>{2, 3, 4})) << "at most max_per_sync, in id order";
  EXPECT_TRUE(core.resend(20, 30).empty());
}

TEST(DescriptorCore, ANewIncarnationStartsAfresh) {
  DescriptorCore core(lidar::ScanContextParams{}, 256);
  ASSERT_NE(core.describe(keyframe(7, 0)), nullptr);
  ASSERT_NE(core.describe(keyframe(7, 1)), nullptr);
  ASSERT_NE(core.describe(keyframe(9, 0)), nullptr) << "keyframe 0 of a restarted front-end is new";
  const auto kept = core.resend(0, 10);
  ASSERT_EQ(kept.size(), 1u);
  EXPECT_EQ(kept[0]->incarnation, 9u);
}

}  // namespace
}  // namespace cdc::descriptor
