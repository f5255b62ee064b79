#include "cdc/loop_closure/peer_reach.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace cdc::loops {
namespace {

using std::chrono::milliseconds;
using std::chrono::seconds;
using Ids = std::vector<uint64_t>;

PeerReachParams params() {
  PeerReachParams p;
  p.silence = seconds(3);
  p.margin = seconds(2);
  p.delay = seconds(1);
  return p;
}

TEST(PeerReach, APeerIsInReachWhileHeardWithinTheSilence) {
  PeerReach r(0, params());
  EXPECT_TRUE(r.in_reach(0, seconds(0)));   // the robot's own services
  EXPECT_FALSE(r.in_reach(1, seconds(0)));  // never heard
  r.heard(1, seconds(10));
  EXPECT_TRUE(r.in_reach(1, seconds(13)));
  EXPECT_FALSE(r.in_reach(1, milliseconds(13001)));
  EXPECT_FALSE(r.in_reach(2, seconds(10)));
}

TEST(PeerReach, APeerHeardAgainAfterASilenceGetsTheLoopsItMayHaveMissed) {
  PeerReach r(0, params());
  for (int t = 0; t <= 10; ++t) {  // both peers heard every second; peer 1's last word at 10 s
    r.heard(1, seconds(t));
    r.heard(2, seconds(t));
    if (t == 1) r.published(0, 0, 0, 1, 0, false, seconds(1));  // long before the silence: acknowledged
  }
  r.published(1, 1, 1, 0, 1, false, seconds(9));   // within the margin: may still have been unacknowledged
  r.published(2, 0, 2, 2, 2, false, seconds(11));  // involves peer 2 only
  r.published(3, 0, 3, 1, 3, false, seconds(12));  // written into the cut
  r.heard(2, seconds(12));                         // peer 2 stays in reach throughout
  EXPECT_TRUE(r.due(seconds(12)).empty());
  r.heard(1, seconds(30));  // back after 20 s
  EXPECT_TRUE(r.due(milliseconds(30500)).empty()) << "waits for discovery to match the readers";
  EXPECT_EQ(r.due(seconds(31)), (Ids{1, 3}));
  EXPECT_TRUE(r.due(seconds(32)).empty()) << "each catch-up goes out once";
  EXPECT_EQ(r.stats().silences, 1u);
  EXPECT_EQ(r.stats().loops_due, 2u);
}

TEST(PeerReach, ShortGapsNeedNoCatchUp) {
  // Within the silence a cut is shorter than the participant lease: DDS retransmits what was not
  // acknowledged by itself.
  PeerReach r(0, params());
  r.heard(1, seconds(0));
  r.published(0, 0, 0, 1, 0, false, seconds(1));
  r.heard(1, seconds(3));
  EXPECT_TRUE(r.due(seconds(10)).empty());
  EXPECT_EQ(r.stats().silences, 0u);
}

TEST(PeerReach, SilencesBeforeTheCatchUpWentOutMerge) {
  PeerReach r(0, params());
  r.heard(1, seconds(0));
  r.published(0, 0, 0, 1, 0, false, seconds(5));   // into the first silence
  r.heard(1, seconds(10));                         // catch-up due at 11 s, but not taken yet
  r.published(1, 0, 1, 2, 1, false, seconds(12));  // peer 2's
  r.published(2, 0, 2, 1, 2, false, seconds(13));  // into the second silence
  r.heard(1, milliseconds(14500));                 // silent again for 4.5 s: due at 15.5 s
  EXPECT_TRUE(r.due(seconds(15)).empty());
  EXPECT_EQ(r.due(seconds(16)), (Ids{0, 2})) << "one catch-up covering both silences";
  EXPECT_EQ(r.stats().silences, 2u);
}

TEST(PeerReach, ALoopDueForTwoPeersIsWrittenOnce) {
  PeerReach r(0, params());
  r.heard(1, seconds(0));
  r.heard(2, seconds(0));
  r.published(0, 1, 0, 2, 0, false, seconds(1));
  r.heard(1, seconds(20));
  r.heard(2, seconds(20));
  EXPECT_EQ(r.due(seconds(21)), (Ids{0}));
  EXPECT_EQ(r.stats().loops_due, 1u);
}

TEST(PeerReach, AWithdrawnLoopIsNotWrittenAgainButItsWithdrawalIs) {
  // Written again after its withdrawal, an accepted loop would be revived at a peer that missed it
  // but took the withdrawal.
  PeerReach r(0, params());
  r.heard(1, seconds(0));
  r.published(0, 0, 10, 1, 20, false, seconds(1));
  r.published(1, 0, 11, 1, 21, false, seconds(1));
  r.published(2, 0, 10, 1, 20, true, seconds(2));
  r.heard(1, seconds(20));
  EXPECT_EQ(r.due(seconds(21)), (Ids{1, 2}));
}

// A long mission: only the newest `keep` loops are kept to be written again; the oldest are forgotten,
// their handles given back so that the caller drops their messages, and counted.
TEST(PeerReach, OnlyTheNewestLoopsAreKeptToBeWrittenAgain) {
  PeerReachParams p = params();
  p.keep = 3;
  PeerReach r(0, p);
  r.heard(1, seconds(0));
  Ids forgotten;
  for (uint64_t id = 0; id < 5; ++id) {  // all written into peer 1's silence
    if (const auto gone =
            r.published(id, 0, static_cast<uint32_t>(id), 1, 0, false, seconds(5 + static_cast<int>(id)))) {
      forgotten.push_back(*gone);
    }
  }
  EXPECT_EQ(forgotten, (Ids{0, 1}));
  EXPECT_EQ(r.stats().forgotten, 2u);
  r.heard(1, seconds(20));
  EXPECT_EQ(r.due(seconds(21)), (Ids{2, 3, 4}));
}

}  // namespace
}  // namespace cdc::loops
