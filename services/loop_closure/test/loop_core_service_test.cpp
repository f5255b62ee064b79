// The loop-closure core as a robot's service runs it, on simulated scans: peers' clouds requested
// and verified when they arrive, reverse searches of a peer's descriptors, a consistent set published
// only once it rests on two keyframes of each robot, a pair of robots' keyframes verified by the
// lower-numbered robot alone. Every loop published is true (1 m / 5 deg).
#include "circle_robots.hpp"

#include <gtest/gtest.h>

#include <set>
#include <vector>

namespace cdc::loops {
namespace {

TEST(LoopCore, RequestsPeerCloudsAndVerifiesWhenTheyArrive) {
  // Robot 1's service: its own keyframes with clouds, robot 0's descriptors only (pose hints).
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;     // inter-robot loops only
  params.peer_request_spacing = 0;  // every candidate's cloud is asked for
  params.lower_robot_verifies =
      false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  std::vector<LoopOut> loops;
  std::set<std::pair<uint32_t, uint32_t>> asked;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(200);
    // A peer's descriptor is searched among this robot's own keyframes (a reverse search).
    LoopEvents ev = core.add_descriptor(c.descriptor(0, k, params), now);
    // The own descriptor may come before its keyframe: the search waits for the keyframe.
    LoopEvents own = core.add_descriptor(c.descriptor(1, k, params), now);
    EXPECT_TRUE(own.requests.empty() && own.loops.empty());
    ev.append(core.add_keyframe_data(c.keyframe(1, k), now));
    for (const auto& r : ev.requests) {
      EXPECT_EQ(r.robot, 0u);
      EXPECT_TRUE(asked.insert({r.robot, r.id}).second) << "asked twice for " << r.id;
      auto more = core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now);
      ev.append(std::move(more));
    }
    loops.insert(loops.end(), ev.loops.begin(), ev.loops.end());
  }
  EXPECT_GE(asked.size(), 5u);
  EXPECT_EQ(core.stats().replies, asked.size());
  EXPECT_EQ(core.pending_requests(), 0u);
  ASSERT_GE(loops.size(), 4u);
  for (const auto& l : loops) {
    EXPECT_FALSE(l.withdrawn);
    EXPECT_EQ(l.robot_a, 0u);
    EXPECT_EQ(l.robot_b, 1u);
    c.expect_true(l);
  }
  // A cloud nobody asked for is counted and ignored.
  core.on_cloud(0, 999, {}, now);
  EXPECT_EQ(core.stats().replies_unexpected, 1u);
}

// Loops that share a keyframe share its cloud: a registration that slid along a featureless stretch
// would slide the same way for each, and they would agree with each other. A consistent set is only
// published once it rests on two keyframes of each robot.
TEST(LoopCore, ASetOfLoopsThroughOneKeyframeIsNotPublished) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;
  params.peer_request_spacing = 0;
  params.max_verify = 4;  // several of robot 0's keyframes against each of robot 1's
  params.lower_robot_verifies =
      false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({0, k}) != 0; ++k) core.add_descriptor(c.descriptor(0, k, params), now);
  auto feed = [&](uint32_t k) {
    LoopEvents ev = core.add_keyframe_data(c.keyframe(1, k), now);
    ev.append(core.add_descriptor(c.descriptor(1, k, params), now));
    for (const auto& r : ev.requests) ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    return ev.loops;
  };
  EXPECT_TRUE(feed(5).empty()) << "loops through robot 1's keyframe 5 alone";
  const uint64_t consistent = core.stats().inter_proposed;
  ASSERT_GE(consistent, 2u) << "the single keyframe closed several (true) loops";
  std::vector<LoopOut> loops = feed(6);
  ASSERT_GE(loops.size(), 3u) << "a second keyframe: the set is published, the first keyframe's loops with it";
  std::set<uint32_t> own;
  for (const auto& l : loops) {
    own.insert(l.keyframe_b);
    c.expect_true(l);
  }
  EXPECT_EQ(own, (std::set<uint32_t>{5, 6}));
}

// A peer that was out of range comes back and its descriptors arrive all at once, after this robot
// has passed every one of those places: the reverse search still finds the loops.
TEST(LoopCore, DescriptorsOfAPeerBackInRangeAreSearchedAmongOwnKeyframes) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;  // inter-robot loops only
  params.peer_request_spacing = 0;
  params.lower_robot_verifies =
      false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    LoopEvents ev = core.add_keyframe_data(c.keyframe(1, k), now);
    ev.append(core.add_descriptor(c.descriptor(1, k, params), now));
    EXPECT_TRUE(ev.requests.empty() && ev.loops.empty()) << "nothing to find before the peer is heard";
  }
  std::vector<LoopOut> loops;
  size_t requests = 0;
  for (uint32_t k = 0; c.truth.count({0, k}) != 0; ++k) {
    now += std::chrono::milliseconds(10);
    LoopEvents ev = core.add_descriptor(c.descriptor(0, k, params), now);
    for (const auto& r : ev.requests) {
      EXPECT_EQ(r.robot, 0u);
      ++requests;
      ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    }
    loops.insert(loops.end(), ev.loops.begin(), ev.loops.end());
  }
  EXPECT_GE(core.stats().reverse_queries, 10u);
  EXPECT_GE(requests, 5u);
  ASSERT_GE(loops.size(), 4u);
  for (const auto& l : loops) {
    EXPECT_EQ(l.robot_a, 0u);
    EXPECT_EQ(l.robot_b, 1u);
    c.expect_true(l);
  }
}

// Each pair of two robots' keyframes is met by both robots' services (the newer keyframe's robot
// searches forward, the other searches that descriptor among its own keyframes): only the lower-
// numbered robot verifies it, so that one cloud crosses instead of one each way.
TEST(LoopCore, APairWithALowerRobotIsLeftToItAndItVerifiesItBothWays) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;  // inter-robot loops only
  params.peer_request_spacing = 0;
  LoopCore core0(params, 0u), core1(params, 1u);
  std::vector<LoopOut> loops0, loops1;
  size_t asked_by_1 = 0;
  std::set<uint32_t> asked_of_1;
  Nanos now{0};
  auto settle = [&](LoopCore& core, LoopEvents ev, std::vector<LoopOut>& loops, uint32_t me) {
    for (size_t i = 0; i < ev.requests.size(); ++i) {
      const CloudWanted r = ev.requests[i];
      EXPECT_NE(r.robot, me);
      if (me == 1) ++asked_by_1;
      if (me == 0) asked_of_1.insert(r.id);
      ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    }
    loops.insert(loops.end(), ev.loops.begin(), ev.loops.end());
  };
  for (uint32_t k = 0; c.truth.count({0, k}) != 0 && c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(200);
    for (uint32_t r : {0u, 1u}) {
      LoopCore& own = r == 0 ? core0 : core1;
      settle(own, own.add_keyframe_data(c.keyframe(r, k), now), r == 0 ? loops0 : loops1, r);
      for (uint32_t to : {0u, 1u}) {  // every descriptor reaches both services
        LoopCore& core = to == 0 ? core0 : core1;
        settle(core, core.add_descriptor(c.descriptor(r, k, params), now), to == 0 ? loops0 : loops1, to);
      }
    }
  }
  EXPECT_EQ(asked_by_1, 0u) << "robot 1 asked robot 0 for clouds";
  EXPECT_TRUE(loops1.empty()) << "robot 1 verified pairs with robot 0";
  EXPECT_EQ(core1.stats().verified, 0u);
  EXPECT_GE(core1.stats().left_to_lower_robot, 10u);
  EXPECT_EQ(core0.stats().left_to_lower_robot, 0u);
  EXPECT_GE(core0.stats().reverse_queries, 10u);
  EXPECT_GE(asked_of_1.size(), 5u);
  ASSERT_GE(loops0.size(), 4u);
  for (const auto& l : loops0) {
    EXPECT_NE(l.robot_a, l.robot_b);
    c.expect_true(l);
  }
}

}  // namespace
}  // namespace cdc::loops
