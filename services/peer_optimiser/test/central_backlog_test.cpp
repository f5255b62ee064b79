#include "cdc/peer_optimiser/central_backlog.hpp"
#include "peer_test_support.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace cdc::peer {
namespace {

using Ids = std::vector<uint32_t>;

// Grace 1 s, one resend step every 200 ms, at most 3 of each per step.
PeerConfig backlog_config() {
  PeerConfig c = config(1);
  c.max_resend_per_step = 3;
  return c;
}

// Keyframes 0..count-1 and own loops 0..loops-1, all sent at time 0.
CentralBacklog sent_at_zero(uint32_t count, uint32_t loops) {
  CentralBacklog b(backlog_config());
  for (uint32_t id = 0; id < count; ++id) b.add_keyframe(id, 0s);
  for (uint32_t seq = 0; seq < loops; ++seq) b.add_own_loop(seq, 0s);
  return b;
}

TEST(CentralBacklog, ResendsWhatWaitedAGraceUnacknowledged) {
  CentralBacklog b = sent_at_zero(5, 2);
  b.on_ack(AckIn{11, 3, 1, 0});
  EXPECT_EQ(b.acknowledged_keyframe(), 1);
  EXPECT_TRUE(b.due(500ms, true).keyframes.empty()) << "before the grace";
  const CentralBacklog::Resend r = b.due(1s, true);
  EXPECT_EQ(r.keyframes, (Ids{2, 3, 4}));
  EXPECT_EQ(r.loops, (Ids{1}));
  EXPECT_TRUE(b.due(1100ms, true).keyframes.empty()) << "within the resend period";
  EXPECT_TRUE(b.due(1200ms, true).keyframes.empty()) << "each waits the grace again";
  EXPECT_EQ(b.due(2s, true).keyframes, (Ids{2, 3, 4}));
}

TEST(CentralBacklog, ALongBacklogGoesOutInChunks) {
  CentralBacklog b = sent_at_zero(8, 0);
  EXPECT_EQ(b.due(1s, true).keyframes, (Ids{0, 1, 2}));
  EXPECT_TRUE(b.due(1100ms, true).keyframes.empty()) << "within the resend period";
  EXPECT_EQ(b.due(1200ms, true).keyframes, (Ids{3, 4, 5}));
  EXPECT_EQ(b.due(1400ms, true).keyframes, (Ids{6, 7}));
}

TEST(CentralBacklog, ARejoinSendsAChunkAtOnceWithoutWaitingTheGrace) {
  CentralBacklog b = sent_at_zero(5, 0);
  b.on_ack(AckIn{11, 3, 0, -1});
  b.on_rejoin();
  EXPECT_EQ(b.due(100ms, true).keyframes, (Ids{1, 2, 3}));
  EXPECT_TRUE(b.due(400ms, true).keyframes.empty()) << "after the rejoin's chunk, the rest waits its grace";
  EXPECT_EQ(b.due(1s, true).keyframes, (Ids{4}));
}

TEST(CentralBacklog, NothingGoesToACentralThatIsNotAlive) {
  CentralBacklog b = sent_at_zero(2, 1);
  b.on_rejoin();
  const CentralBacklog::Resend none = b.due(5s, false);
  EXPECT_TRUE(none.keyframes.empty());
  EXPECT_TRUE(none.loops.empty());
  const CentralBacklog::Resend r = b.due(5s, true);
  EXPECT_EQ(r.keyframes, (Ids{0, 1}));
  EXPECT_EQ(r.loops, (Ids{0}));
}

TEST(CentralBacklog, ANewCentralIncarnationHasAcknowledgedNothing) {
  CentralBacklog b = sent_at_zero(3, 0);
  b.on_ack(AckIn{11, 3, 2, -1});
  b.on_rejoin();
  EXPECT_TRUE(b.due(100ms, true).keyframes.empty());
  b.forget_acknowledgements(12);
  EXPECT_EQ(b.acknowledged_keyframe(), -1);
  b.on_rejoin();
  EXPECT_EQ(b.due(400ms, true).keyframes, (Ids{0, 1, 2}));
}

}  // namespace
}  // namespace cdc::peer
