// Retrieval: which descriptors are searched, among which keyframes, and which candidates come out.
#include "cdc/loop_closure/retrieval.hpp"

#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <vector>

namespace cdc::loops {
namespace {

using test::place_context;

DescriptorIn descriptor(uint32_t robot, uint32_t id, uint32_t place, int shift = 0) {
  return DescriptorIn{robot, id, place_context(place, shift), Eigen::Isometry3d::Identity()};
}

// Robot `robot`'s keyframes first..last, each at a place of its own (place = 100 * robot + id).
void describe(Retrieval& r, uint32_t robot, uint32_t first, uint32_t last) {
  for (uint32_t id = first; id <= last; ++id) {
    ASSERT_TRUE(r.first_description({robot, id}));
    EXPECT_TRUE(r.search(descriptor(robot, id, 100 * robot + id), true).empty());
  }
}

// Keyframes 10 m apart straight on, ids first..last.
void drive_straight(IntraGate& gate, uint32_t first, uint32_t last) {
  for (uint32_t id = first; id <= last; ++id) gate.add(0, id, test::planar(10, 0, 0));
}

TEST(IntraGate, AnOwnLoopIsPlausibleOnlyWithinTheGateByTheRobotsOdometry) {
  IntraGate gate(15, 0.05);
  drive_straight(gate, 0, 10);
  EXPECT_TRUE(gate.plausible({0, 10}, {0, 9}));   // 10 m apart: within 15 + 0.05 * 10
  EXPECT_FALSE(gate.plausible({0, 10}, {0, 8}));  // 20 m: beyond 15 + 0.05 * 20
  EXPECT_FALSE(gate.plausible({0, 10}, {0, 0}));
}

TEST(IntraGate, TheGateWidensWithThePathDrivenBetweenTheTwo) {
  IntraGate gate(15, 0.5);
  drive_straight(gate, 0, 10);
  EXPECT_TRUE(gate.plausible({0, 10}, {0, 8}));   // 20 m within 15 + 0.5 * 20
  EXPECT_TRUE(gate.plausible({0, 10}, {0, 7}));   // 30 m: on the limit
  EXPECT_FALSE(gate.plausible({0, 10}, {0, 5}));  // 50 m beyond 15 + 0.5 * 50
}

TEST(IntraGate, WithoutAnUnbrokenChainOrWithoutAGateEveryLoopIsPlausible) {
  IntraGate gate(15, 0.05);
  drive_straight(gate, 5, 8);  // the robot's first keyframe here starts its chain
  EXPECT_FALSE(gate.plausible({0, 8}, {0, 5}));
  gate.add(0, 20, test::planar(10, 0, 0));  // after a gap: not chained
  EXPECT_TRUE(gate.plausible({0, 20}, {0, 5}));
  EXPECT_TRUE(gate.plausible({0, 8}, {1, 0}));  // a keyframe the gate never saw
  IntraGate off(0, 0);
  drive_straight(off, 0, 10);
  EXPECT_TRUE(off.plausible({0, 10}, {0, 0}));
}

LoopParams params() {
  LoopParams p;
  p.exclude_recent = 5;
  return p;
}

// The job's starting guess turns by yaw_rad about z.
void expect_yaw(const VerificationJob& job, double yaw_rad) {
  EXPECT_TRUE(
      job.guess.linear().isApprox(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix(), 1e-9));
  EXPECT_LT(job.guess.translation().norm(), 1e-12);
}

TEST(Retrieval, AQueryRobotsDescriptorWaitsForItsKeyframe) {
  Retrieval r(params(), 1u);
  EXPECT_TRUE(r.waits_for_keyframe(descriptor(1, 0, 0), false));
  EXPECT_FALSE(r.waits_for_keyframe(descriptor(1, 0, 0), true));
  EXPECT_FALSE(r.waits_for_keyframe(descriptor(0, 0, 0), false)) << "a peer's keyframe is never held here";
  r.defer(descriptor(1, 0, 7));
  const std::optional<DescriptorIn> back = r.take_deferred({1, 0});
  ASSERT_TRUE(back.has_value());
  EXPECT_EQ(back->context.cells, place_context(7).cells);
  EXPECT_FALSE(r.take_deferred({1, 0}).has_value());
  ASSERT_TRUE(r.first_description({1, 0}));
  EXPECT_FALSE(r.waits_for_keyframe(descriptor(1, 0, 0), false)) << "described already";
  Retrieval offline(params(), std::nullopt);
  EXPECT_TRUE(offline.waits_for_keyframe(descriptor(3, 0, 0), false));
  EXPECT_FALSE(offline.is_peer(3));
}

TEST(Retrieval, BeyondTheDeferredLimitTheOldestEntersTheDatabaseUnsearched) {
  Retrieval r(params(), 1u);
  for (uint32_t id = 0; id <= Retrieval::kMaxDeferred; ++id) r.defer(descriptor(1, id, id));
  EXPECT_EQ(r.stats().deferred_dropped, 1u);
  EXPECT_EQ(r.size(), 1u);
  EXPECT_FALSE(r.take_deferred({1, 0}).has_value());
  EXPECT_TRUE(r.take_deferred({1, 1}).has_value());
  EXPECT_FALSE(r.waits_for_keyframe(descriptor(1, 0, 0), false)) << "it counts as described";
  EXPECT_EQ(r.stats().queries, 0u);
}

TEST(Retrieval, ARepeatedDescriptorIsCounted) {
  Retrieval r(params(), std::nullopt);
  EXPECT_TRUE(r.first_description({0, 4}));
  EXPECT_FALSE(r.first_description({0, 4}));
  EXPECT_TRUE(r.first_description({1, 4}));
  EXPECT_EQ(r.stats().duplicate_descriptors, 1u);
}

TEST(Retrieval, AForwardSearchFindsAnEarlierVisitWithTheYawBetweenThem) {
  Retrieval r(params(), std::nullopt);
  describe(r, 0, 0, 10);
  ASSERT_TRUE(r.first_description({0, 11}));
  const std::vector<VerificationJob> jobs = r.search(descriptor(0, 11, 3, 7), true);  // place 3, turned
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].query, (KeyframeId{0, 11}));
  EXPECT_EQ(jobs[0].candidate, (KeyframeId{0, 3}));
  // The query is turned by the match's yaw relative to the candidate: the guess starts at Rz(-yaw).
  expect_yaw(jobs[0], -lidar::compare(place_context(3, 7), place_context(3)).yaw_rad);
  // Keyframe 9 is one of the exclude_recent (5) before keyframe 12.
  ASSERT_TRUE(r.first_description({0, 12}));
  EXPECT_TRUE(r.search(descriptor(0, 12, 9), true).empty());
  EXPECT_EQ(r.stats().queries, 13u);
  EXPECT_EQ(r.stats().candidates, 1u);
  EXPECT_EQ(r.size(), 13u);
}

TEST(Retrieval, OnlyCandidatesWithinTheDistanceAndTheVerifyLimitAreTaken) {
  Retrieval r(params(), std::nullopt);
  for (uint32_t id = 0; id < 3; ++id) {  // three keyframes of one place
    ASSERT_TRUE(r.first_description({0, id}));
    r.search(descriptor(0, id, 50, static_cast<int>(id)), true);
  }
  describe(r, 0, 3, 10);
  ASSERT_TRUE(r.first_description({0, 20}));
  EXPECT_EQ(r.search(descriptor(0, 20, 50), true).size(), 2u) << "max_verify";
  ASSERT_TRUE(r.first_description({0, 21}));
  EXPECT_TRUE(r.search(descriptor(0, 21, 77), true).empty()) << "a new place";
  EXPECT_EQ(r.stats().candidates, 2u);
}

TEST(Retrieval, APeersDescriptorIsSearchedAmongThisRobotsOwnKeyframes) {
  Retrieval r(params(), 0u);  // robot 0's service
  describe(r, 0, 0, 5);
  describe(r, 1, 0, 2);  // peer's places no own keyframe saw
  ASSERT_TRUE(r.first_description({1, 3}));
  const std::vector<VerificationJob> jobs = r.search(descriptor(1, 3, 4, 5), false);  // the peer at place 4
  ASSERT_EQ(jobs.size(), 1u);
  // The job's query is this robot's keyframe, its candidate the peer's: the yaw changes sign.
  EXPECT_EQ(jobs[0].query, (KeyframeId{0, 4}));
  EXPECT_EQ(jobs[0].candidate, (KeyframeId{1, 3}));
  expect_yaw(jobs[0], lidar::compare(place_context(4, 5), place_context(4)).yaw_rad);
  // A peer's descriptor is never matched with the peer's own keyframes.
  ASSERT_TRUE(r.first_description({1, 4}));
  EXPECT_TRUE(r.search(descriptor(1, 4, 101), false).empty());
  EXPECT_EQ(r.stats().reverse_queries, 5u);
  EXPECT_EQ(r.stats().queries, 6u);
}

TEST(Retrieval, APairWithALowerNumberedRobotIsLeftToThatRobot) {
  for (const bool lower_verifies : {true, false}) {
    LoopParams p = params();
    p.lower_robot_verifies = lower_verifies;
    Retrieval r(p, 1u);  // robot 1's service
    describe(r, 0, 0, 5);
    describe(r, 1, 0, 2);
    ASSERT_TRUE(r.first_description({1, 3}));
    const size_t forward = r.search(descriptor(1, 3, 4), true).size();  // robot 0's place 4
    ASSERT_TRUE(r.first_description({0, 6}));
    const size_t reverse = r.search(descriptor(0, 6, 101), false).size();  // robot 1's place 1
    EXPECT_EQ(forward, lower_verifies ? 0u : 1u);
    EXPECT_EQ(reverse, lower_verifies ? 0u : 1u);
    EXPECT_EQ(r.stats().left_to_lower_robot, lower_verifies ? 2u : 0u);
  }
}

TEST(Retrieval, OwnCandidatesTheOdometryPutsFarAwayAreGated) {
  for (const bool odometry : {false, true}) {
    Retrieval r(params(), std::nullopt);
    if (odometry) {
      for (uint32_t id = 0; id <= 20; ++id) r.add_odometry(0, id, test::planar(10, 0, 0));
    }
    describe(r, 0, 0, 19);
    ASSERT_TRUE(r.first_description({0, 20}));
    // Place 2 again, 180 m behind by the odometry: beyond 15 m + 5 % of the 180 m driven.
    EXPECT_EQ(r.search(descriptor(0, 20, 2), true).size(), odometry ? 0u : 1u);
    EXPECT_EQ(r.stats().intra_gated > 0, odometry);
    ASSERT_TRUE(r.first_description({1, 0}));
    EXPECT_FALSE(r.search(descriptor(1, 0, 2), true).empty()) << "another robot's keyframe is not gated";
  }
}

}  // namespace
}  // namespace cdc::loops

namespace cdc::loops {
namespace {

// A view of the keyframe from `y` metres to its left, holding the descriptor of `place`.
std::vector<ShiftedView> view_of(uint32_t place, double y) { return {{place_context(place), {0, y, 0}}}; }

TEST(Retrieval, AViewBesideAKeyframeMatchesAPlaceSeenALaneAside) {
  Retrieval r(params(), 0u);  // robot 0's service
  describe(r, 0, 0, 2);
  // Own keyframe 3 (place 3) seen from 3.5 m to its left looks like place 200: a peer's descriptor
  // of place 200, turned, is searched in reverse and meets that view.
  ASSERT_TRUE(r.first_description({0, 3}));
  r.add_views({0, 3}, view_of(200, 3.5));
  EXPECT_TRUE(r.search(descriptor(0, 3, 3), true).empty());
  EXPECT_EQ(r.size(), 5u) << "the keyframe's descriptor and its view";
  ASSERT_TRUE(r.first_description({1, 7}));
  std::vector<VerificationJob> jobs = r.search(descriptor(1, 7, 200, 5), false);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].query, (KeyframeId{0, 3}));
  EXPECT_EQ(jobs[0].candidate, (KeyframeId{1, 7}));
  // The view's sensor (3.5 m left of keyframe 3) sees the peer's at Rz(-yaw): T_peer_own is its inverse.
  const double yaw = lidar::compare(place_context(200, 5), place_context(200)).yaw_rad;
  const Eigen::Isometry3d T_own_peer =
      Eigen::Translation3d(0, 3.5, 0) * Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ());
  EXPECT_TRUE(jobs[0].guess.isApprox(T_own_peer.inverse(), 1e-9));
  // Own keyframe 8's view from 3.5 m to its right is the peer's place 200: the forward search
  // finds the peer's keyframe through it (views are searched among descriptors only).
  describe(r, 0, 4, 7);
  ASSERT_TRUE(r.first_description({0, 8}));
  r.add_views({0, 8}, view_of(200, -3.5));
  jobs = r.search(descriptor(0, 8, 8), true);
  ASSERT_EQ(jobs.size(), 1u);
  EXPECT_EQ(jobs[0].query, (KeyframeId{0, 8}));
  EXPECT_EQ(jobs[0].candidate, (KeyframeId{1, 7}));
  const double yaw_f = lidar::compare(place_context(200), place_context(200, 5)).yaw_rad;
  const Eigen::Isometry3d T_peer_own =
      Eigen::AngleAxisd(-yaw_f, Eigen::Vector3d::UnitZ()) * Eigen::Translation3d(0, 3.5, 0);
  EXPECT_TRUE(jobs[0].guess.isApprox(T_peer_own, 1e-9));
}

}  // namespace
}  // namespace cdc::loops
