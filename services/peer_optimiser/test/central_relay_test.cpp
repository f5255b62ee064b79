#include "cdc/peer_optimiser/central_relay.hpp"
#include "peer_test_support.hpp"

#include <gtest/gtest.h>

namespace cdc::peer {
namespace {

// A central result holding own keyframes 0..newest.
CentralResult holding(uint32_t newest, bool from_hint = false) {
  CentralResult r;
  for (uint32_t id = 0; id <= newest; ++id) r.poses.emplace_back(id, pose_at(id));
  r.from_hint = from_hint;
  return r;
}

// Hands the relay a result and tells whether it relays it at this step.
bool relays(CentralRelay& relay, const CentralResult& r) {
  relay.on_result(r);
  return relay.update();
}

TEST(CentralRelay, RelaysEveryPlacedResultAndNoHint) {
  CentralRelay relay;
  EXPECT_FALSE(relay.update()) << "no result yet";
  EXPECT_TRUE(relays(relay, holding(5)));
  EXPECT_TRUE(relay.update()) << "still current at the next step";
  EXPECT_FALSE(relays(relay, holding(6, true))) << "a placement from the robot's own hint carries no correction";
  EXPECT_TRUE(relays(relay, holding(6)));
}

TEST(CentralRelay, AfterARejoinRelaysOnlyAResultHoldingTheNewestKeyframeThen) {
  CentralRelay relay;
  ASSERT_TRUE(relays(relay, holding(9)));
  relay.on_rejoin(20);
  EXPECT_FALSE(relay.update()) << "the result from before the cut";
  EXPECT_FALSE(relays(relay, holding(20, true))) << "a hint holds every keyframe but does not reach the frontier";
  EXPECT_FALSE(relays(relay, holding(15))) << "part of the backlog";
  EXPECT_TRUE(relays(relay, holding(20)));
  EXPECT_TRUE(relays(relay, holding(21)));
}

TEST(CentralRelay, ARejoinBeforeAnyKeyframeWaitsForNothing) {
  CentralRelay relay;
  relay.on_rejoin(std::nullopt);
  EXPECT_TRUE(relays(relay, holding(3)));
}

TEST(CentralRelay, AResultBehindOneRelayedWaitsUntilItCatchesUp) {
  CentralRelay relay;
  ASSERT_TRUE(relays(relay, holding(20)));
  EXPECT_FALSE(relays(relay, holding(12)));
  EXPECT_FALSE(relays(relay, holding(19)));
  EXPECT_TRUE(relays(relay, holding(20)));
}

TEST(CentralRelay, ANewCentralIncarnationHasRelayedNothing) {
  CentralRelay relay;
  ASSERT_TRUE(relays(relay, holding(20)));
  relay.forget_relayed();
  EXPECT_TRUE(relays(relay, holding(12)));
}

TEST(CentralRelay, KnowsWhetherTheCentralHasGivenPoses) {
  CentralRelay relay;
  EXPECT_FALSE(relay.has_poses());
  EXPECT_TRUE(relay.poses().empty());
  EXPECT_FALSE(relay.last());
  relay.on_result(CentralResult{});
  EXPECT_FALSE(relay.has_poses());
  EXPECT_TRUE(relay.last());
  relay.on_result(holding(3));
  EXPECT_TRUE(relay.has_poses());
  EXPECT_EQ(relay.poses().size(), 4u);
}

}  // namespace
}  // namespace cdc::peer
