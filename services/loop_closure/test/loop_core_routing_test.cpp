// LoopCore as the composition of its parts, on synthetic descriptors and clouds: a candidate is
// verified at once when its cloud is held, requested otherwise and verified when the cloud comes, or
// re-aimed at a neighbour already requested; replies are told apart; stats() gathers every part's.
#include "cdc/loop_closure/loop_core.hpp"

#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace cdc::loops {
namespace {

using test::planar;

// Robot 1's service; it verifies its pairs with robot 0 itself.
LoopParams params(uint32_t spacing = 0) {
  LoopParams p;
  p.lower_robot_verifies = false;
  p.peer_request_spacing = spacing;
  return p;
}

// Peer robot 0's keyframe k: at place 10 + k, 2 m apart along x in the peer's odometry.
DescriptorIn peer(uint32_t k) { return DescriptorIn{0, k, test::place_context(10 + k), planar(2.0 * k, 0, 0)}; }
// Robot 1's own keyframe k, at `place`.
DescriptorIn own(uint32_t k, uint32_t place) {
  return DescriptorIn{1, k, test::place_context(place), Eigen::Isometry3d::Identity()};
}
KeyframeIn own_keyframe(uint32_t k) {
  KeyframeIn kf;
  kf.robot = 1;
  kf.id = k;
  kf.cloud = test::street_scene(1);
  return kf;
}
// The scene as peer keyframe k saw it (1 m from this robot's keyframes, which all see it from the origin).
std::vector<Eigen::Vector3f> peer_cloud() { return test::seen_from(test::street_scene(1), planar(1, 0, 0)); }

TEST(LoopCoreRouting, ACandidateNotHeldIsRequestedAndVerifiedWhenItsCloudComes) {
  LoopCore core(params(), 1u);
  EXPECT_TRUE(core.add_descriptor(peer(0), Nanos(0)).requests.empty()) << "no own keyframe yet";
  EXPECT_TRUE(core.add_descriptor(own(0, 10), Nanos(0)).requests.empty()) << "waits for its keyframe";
  const LoopEvents asked = core.add_keyframe_data(own_keyframe(0), Nanos(0));
  ASSERT_EQ(asked.requests.size(), 1u);
  EXPECT_EQ(asked.requests[0].robot, 0u);
  EXPECT_EQ(asked.requests[0].id, 0u);
  EXPECT_TRUE(core.is_wanted(0, 0));
  EXPECT_EQ(core.reply_use(0, 0, true), ReplyUse::kCloud);
  EXPECT_EQ(core.reply_use(0, 0, false), ReplyUse::kNotHeld);
  EXPECT_EQ(core.reply_use(0, 5, true), ReplyUse::kUnrequested);
  const LoopEvents verified = core.on_cloud(0, 0, peer_cloud(), Nanos(0));
  ASSERT_EQ(verified.verifications.size(), 1u);
  EXPECT_TRUE(verified.verifications[0].passed);
  EXPECT_TRUE(verified.loops.empty()) << "one loop is not a set of min_inter_support";
  EXPECT_EQ(core.reply_use(0, 0, true), ReplyUse::kDuplicate);
  const LoopStats s = core.stats();
  EXPECT_EQ(s.requests, 1u);
  EXPECT_EQ(s.replies, 1u);
  EXPECT_EQ(s.verified, 1u);
  EXPECT_EQ(s.inter_proposed, 1u);
  EXPECT_EQ(s.reverse_queries, 1u);
  EXPECT_EQ(s.queries, 1u);
  EXPECT_EQ(s.prepared, 2u);
}

TEST(LoopCoreRouting, ACandidateHeldIsVerifiedAtOnceAndEachPairOnce) {
  LoopCore core(params(), 1u);
  core.add_descriptor(peer(0), Nanos(0));
  core.add_keyframe_data(own_keyframe(0), Nanos(0));
  const LoopEvents first = core.add_descriptor(own(0, 10), Nanos(0));
  ASSERT_EQ(first.requests.size(), 1u);
  core.on_cloud(0, 0, peer_cloud(), Nanos(0));
  core.add_keyframe_data(own_keyframe(1), Nanos(0));
  const LoopEvents second = core.add_descriptor(own(1, 10), Nanos(0));  // the same place again
  EXPECT_TRUE(second.requests.empty());
  ASSERT_EQ(second.verifications.size(), 1u);
  EXPECT_EQ(second.verifications[0].query_id, 1u);
  EXPECT_TRUE(core.add_descriptor(own(1, 10), Nanos(0)).verifications.empty()) << "a repeated descriptor";
  EXPECT_EQ(core.stats().duplicate_descriptors, 1u);
  EXPECT_EQ(core.stats().verified, 2u);
}

TEST(LoopCoreRouting, ACandidateNextToARequestedOneIsVerifiedAgainstItsCloud) {
  LoopCore core(params(5), 1u);
  for (uint32_t k = 0; k < 4; ++k) core.add_descriptor(peer(k), Nanos(0));
  core.add_keyframe_data(own_keyframe(0), Nanos(0));
  ASSERT_EQ(core.add_descriptor(own(0, 10), Nanos(0)).requests.size(), 1u);  // peer keyframe 0
  core.add_keyframe_data(own_keyframe(1), Nanos(0));
  EXPECT_TRUE(core.add_descriptor(own(1, 12), Nanos(0)).requests.empty()) << "peer keyframe 2: re-aimed at 0";
  EXPECT_EQ(core.stats().verified_with_neighbour, 1u);
  EXPECT_EQ(core.pending_requests(), 1u);
  EXPECT_EQ(core.on_cloud(0, 0, peer_cloud(), Nanos(0)).verifications.size(), 2u) << "both jobs wait for one cloud";
}

TEST(LoopCoreRouting, ParkedRequestsAreAskedAgainThroughTick) {
  LoopParams p = params();
  p.request_timeout = std::chrono::seconds(1);
  p.request_retry = std::chrono::seconds(1);
  LoopCore core(p, 1u);
  bool in_reach = false;
  core.set_reachable([&](uint32_t) { return in_reach; });
  core.add_descriptor(peer(0), Nanos(0));
  core.add_keyframe_data(own_keyframe(0), Nanos(0));
  EXPECT_TRUE(core.add_descriptor(own(0, 10), Nanos(0)).requests.empty()) << "owner out of reach";
  EXPECT_EQ(core.parked_requests(), 1u);
  EXPECT_TRUE(core.tick(std::chrono::seconds(5)).requests.empty());
  in_reach = true;
  EXPECT_EQ(core.tick(std::chrono::seconds(6)).requests.size(), 1u);
  core.on_cloud_missing(0, 0, std::chrono::seconds(6));
  EXPECT_EQ(core.tick(std::chrono::seconds(7)).requests.size(), 1u);
  EXPECT_EQ(core.stats().unreachable, 1u);
  EXPECT_EQ(core.stats().missing, 1u);
  EXPECT_EQ(core.stats().requests_retried, 2u);
}

}  // namespace
}  // namespace cdc::loops
