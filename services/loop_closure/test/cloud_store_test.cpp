// The clouds held by the loop-closure core: local ones for good, received ones the most recent
// cloud_cache, and the most recently used prepared_clouds ready for registration.
#include "cdc/loop_closure/cloud_store.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

namespace cdc::loops {
namespace {

// 100 points 1 m apart on a plane, shifted by `offset` along x (voxel_m 0.4 keeps every one).
std::vector<Eigen::Vector3f> grid(float offset = 0) {
  std::vector<Eigen::Vector3f> cloud;
  for (int i = 0; i < 10; ++i) {
    for (int j = 0; j < 10; ++j) cloud.emplace_back(offset + static_cast<float>(i), static_cast<float>(j), 0.0f);
  }
  return cloud;
}

LoopParams params(size_t cache, size_t prepared) {
  LoopParams p;
  p.cloud_cache = cache;
  p.prepared_clouds = prepared;
  return p;
}

TEST(CloudStore, CloudsAreHeldDownsampledAndLocalOnesWithWhereUpIs) {
  CloudStore store(params(4, 2));
  std::vector<Eigen::Vector3f> clump(50, Eigen::Vector3f(0.1f, 0.1f, 0.1f));
  clump.emplace_back(0.2f, 0.2f, 0.2f);  // the same 0.4 m voxel
  const Eigen::Vector3d up = Eigen::Vector3d(0.1, 0, 1).normalized();
  store.add_local({0, 3}, clump, up);
  ASSERT_NE(store.find({0, 3}), nullptr);
  EXPECT_EQ(store.find({0, 3})->size(), 1u);
  EXPECT_TRUE(store.is_local({0, 3}));
  EXPECT_TRUE(store.up({0, 3}).isApprox(up));
  EXPECT_EQ(store.up({1, 3}), Eigen::Vector3d::UnitZ()) << "unknown: +z";
  EXPECT_EQ(store.find({1, 3}), nullptr);
  store.add_received({0, 3}, grid());  // a local keyframe is not replaced by a received copy
  EXPECT_EQ(store.find({0, 3})->size(), 1u);
  store.add_received({1, 3}, grid());
  EXPECT_TRUE(store.holds({1, 3}));
  EXPECT_FALSE(store.is_local({1, 3}));
  EXPECT_EQ(store.find({1, 3})->size(), 100u);
}

TEST(CloudStore, OnlyTheMostRecentlyReceivedCloudsAreKept) {
  CloudStore store(params(2, 2));
  store.add_local({0, 0}, grid(), Eigen::Vector3d::UnitZ());
  for (uint32_t id = 0; id < 3; ++id) store.add_received({1, id}, grid());
  EXPECT_FALSE(store.holds({1, 0}));
  EXPECT_TRUE(store.holds({1, 1}));
  EXPECT_TRUE(store.holds({1, 2}));
  EXPECT_TRUE(store.holds({0, 0})) << "local clouds stay";
}

TEST(CloudStore, RecentlyUsedCloudsStayReadyForRegistration) {
  CloudStore store(params(8, 2));
  for (uint32_t id = 0; id < 3; ++id) store.add_local({0, id}, grid(), Eigen::Vector3d::UnitZ());
  const auto a = store.prepared({0, 0});
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->size(), 100u);
  EXPECT_EQ(store.prepared({0, 0}), a);
  store.prepared({0, 1});
  store.prepared({0, 0});
  store.prepared({0, 2});  // drops 1, the least recently used
  EXPECT_EQ(store.prepared({0, 0}), a);
  EXPECT_EQ(store.stats().prepared, 3u);
  store.prepared({0, 1});
  EXPECT_EQ(store.stats().prepared, 4u);
  EXPECT_EQ(store.stats().prepared_reused, 3u);
  EXPECT_EQ(store.prepared({5, 5}), nullptr) << "not held";
}

TEST(CloudStore, AReplacedOrDroppedCloudIsPreparedAfresh) {
  CloudStore store(params(2, 4));
  store.add_received({1, 0}, grid());
  const auto first = store.prepared({1, 0});
  store.add_received({1, 1}, grid());
  store.add_received({1, 0}, grid(5));  // received again: now the most recent
  const auto second = store.prepared({1, 0});
  ASSERT_NE(second, nullptr);
  EXPECT_NE(second, first);
  const auto& held = *store.find({1, 0});
  EXPECT_TRUE(std::any_of(held.begin(), held.end(), [](const Eigen::Vector3f& p) { return p.x() > 13; }))
      << "the new cloud";
  store.add_received({1, 2}, grid());  // drops {1, 1}
  EXPECT_TRUE(store.holds({1, 0}));
  EXPECT_FALSE(store.holds({1, 1}));
  store.add_received({1, 3}, grid());  // drops {1, 0}, and its prepared cloud
  EXPECT_EQ(store.prepared({1, 0}), nullptr);
  EXPECT_EQ(store.stats().prepared_reused, 0u);
  CloudStore none(params(1, 0));
  none.add_received({1, 0}, grid());
  EXPECT_NE(none.prepared({1, 0}), none.prepared({1, 0}));
  EXPECT_EQ(none.stats().prepared, 2u);
}

}  // namespace
}  // namespace cdc::loops
