#include "cdc/loop_closure/descriptor_sequencer.hpp"
#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace cdc::loops {
namespace {

using std::chrono::seconds;

using test::desc;

std::vector<uint32_t> ids(const std::vector<DescriptorIn>& v) {
  std::vector<uint32_t> out;
  for (const auto& d : v) out.push_back(d.id);
  return out;
}

const auto always = [](uint32_t) { return true; };

TEST(DescriptorSequencer, DeliversInOrderAndDropsDuplicates) {
  DescriptorSequencer s;
  EXPECT_EQ(ids(s.add(desc(1, 0))), (std::vector<uint32_t>{0}));
  EXPECT_EQ(ids(s.add(desc(1, 1))), (std::vector<uint32_t>{1}));
  EXPECT_TRUE(s.add(desc(1, 1)).empty());
  EXPECT_TRUE(s.add(desc(1, 0)).empty());
  EXPECT_EQ(s.stats().duplicates, 2u);
  EXPECT_EQ(s.next_expected(1), 2u);
  EXPECT_EQ(s.next_expected(2), 0u);
  std::vector<DescriptorIn> released;
  EXPECT_TRUE(s.wanted(Nanos(0), always, released).empty()) << "no gap, nothing to ask for";
}

TEST(DescriptorSequencer, HoldsBackAfterAGapAsksForItAndReleasesWhenFilled) {
  DescriptorSequencer s;
  s.add(desc(2, 0));
  EXPECT_TRUE(s.add(desc(2, 4)).empty());
  EXPECT_TRUE(s.add(desc(2, 5)).empty());
  EXPECT_EQ(s.held(2), 2u);
  std::vector<DescriptorIn> released;
  const auto w = s.wanted(Nanos(0), always, released);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].robot, 2u);
  EXPECT_EQ(w[0].first, 1u);
  EXPECT_EQ(w[0].last, 3u);
  EXPECT_TRUE(released.empty());
  // Asked again only after the resend interval.
  EXPECT_TRUE(s.wanted(seconds(1), always, released).empty());
  EXPECT_EQ(s.wanted(seconds(2), always, released).size(), 1u);
  // The missing range arrives (a resend, in order): everything comes out in keyframe order.
  EXPECT_EQ(ids(s.add(desc(2, 1))), (std::vector<uint32_t>{1}));
  EXPECT_EQ(ids(s.add(desc(2, 3))), (std::vector<uint32_t>{}));
  EXPECT_EQ(ids(s.add(desc(2, 2))), (std::vector<uint32_t>{2, 3, 4, 5}));
  EXPECT_EQ(s.held(2), 0u);
  EXPECT_TRUE(s.wanted(seconds(10), always, released).empty());
}

TEST(DescriptorSequencer, AGapThatIsBeingFilledIsNotAskedForAgain) {
  DescriptorSequencer s;
  s.add(desc(3, 0));
  s.add(desc(3, 10));
  std::vector<DescriptorIn> released;
  ASSERT_EQ(s.wanted(seconds(0), always, released).size(), 1u);  // 1..9
  s.add(desc(3, 1));
  s.add(desc(3, 2));  // the answer is arriving
  EXPECT_TRUE(s.wanted(seconds(2), always, released).empty());
  EXPECT_TRUE(s.wanted(seconds(3), always, released).empty());
  // No progress for a whole interval: ask for the rest.
  const auto w = s.wanted(seconds(4), always, released);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].first, 3u);
  EXPECT_EQ(w[0].last, 9u);
  EXPECT_EQ(s.stats().sync_requests, 2u);
}

TEST(DescriptorSequencer, AnOwnerOutOfReachIsNotAsked) {
  DescriptorSequencer s;
  s.add(desc(1, 3));  // ids 0..2 missed
  std::vector<DescriptorIn> released;
  EXPECT_TRUE(s.wanted(
                   seconds(0), [](uint32_t) { return false; }, released)
                  .empty());
  EXPECT_TRUE(s.wanted(
                   seconds(100), [](uint32_t) { return false; }, released)
                  .empty());
  EXPECT_TRUE(released.empty()) << "a gap is not given up while its owner cannot be asked";
  EXPECT_EQ(s.wanted(seconds(101), always, released).size(), 1u);
}

TEST(DescriptorSequencer, AGapNeverFilledIsSkippedAfterTheAttempts) {
  SequencerParams p;
  p.max_attempts = 3;
  DescriptorSequencer s(p);
  s.add(desc(1, 0));
  s.add(desc(1, 2));  // 1 is never sent
  s.add(desc(1, 3));
  s.add(desc(1, 6));  // 4, 5 missing too
  std::vector<DescriptorIn> released;
  for (int i = 0; i < 3; ++i) {
    const auto w = s.wanted(seconds(2 * i), always, released);
    ASSERT_EQ(w.size(), 1u);
    EXPECT_EQ(w[0].first, 1u);
    EXPECT_EQ(w[0].last, 1u);
  }
  EXPECT_TRUE(released.empty());
  // Fourth time: the gap at 1 is given up, 2 and 3 come out, and the next gap (4..5) is asked for.
  const auto w = s.wanted(seconds(6), always, released);
  EXPECT_EQ(ids(released), (std::vector<uint32_t>{2, 3}));
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].first, 4u);
  EXPECT_EQ(w[0].last, 5u);
  EXPECT_EQ(s.stats().gaps_skipped, 1u);
  EXPECT_EQ(s.stats().ids_skipped, 1u);
}

TEST(DescriptorSequencer, HoldingIsBounded) {
  SequencerParams p;
  p.max_held = 3;
  DescriptorSequencer s(p);
  s.add(desc(0, 10));
  s.add(desc(0, 11));
  s.add(desc(0, 12));
  EXPECT_EQ(ids(s.add(desc(0, 13))), (std::vector<uint32_t>{10, 11, 12, 13}));
  EXPECT_EQ(s.stats().ids_skipped, 10u);
  EXPECT_EQ(s.next_expected(0), 14u);
}

TEST(DescriptorSequencer, ATailNothingCameAfterIsAskedForFromTheOwnersMark) {
  // Robot 3 described 0..5; 3..5 were made out of range just before it stopped making keyframes, so no
  // later descriptor shows the gap. Its status says its last keyframe is 5.
  DescriptorSequencer s;
  for (uint32_t i = 0; i < 3; ++i) s.add(desc(3, i));
  s.announce(3, 5, Nanos(0));
  EXPECT_EQ(s.missing(), 3u);
  std::vector<DescriptorIn> released;
  EXPECT_TRUE(s.wanted(seconds(1), always, released).empty()) << "live descriptors may still be in flight";
  s.announce(3, 4, seconds(1));  // an older mark changes nothing
  const auto w = s.wanted(seconds(2), always, released);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].robot, 3u);
  EXPECT_EQ(w[0].first, 3u);
  EXPECT_EQ(w[0].last, 5u);
  EXPECT_EQ(ids(s.add(desc(3, 3))), (std::vector<uint32_t>{3}));
  EXPECT_EQ(ids(s.add(desc(3, 4))), (std::vector<uint32_t>{4}));
  EXPECT_EQ(ids(s.add(desc(3, 5))), (std::vector<uint32_t>{5}));
  EXPECT_EQ(s.missing(), 0u);
  EXPECT_TRUE(s.wanted(seconds(10), always, released).empty());
  // A robot never heard from but announced is asked for from its first keyframe.
  s.announce(4, 1, seconds(10));
  const auto w4 = s.wanted(seconds(12), always, released);
  ASSERT_EQ(w4.size(), 1u);
  EXPECT_EQ(w4[0].robot, 4u);
  EXPECT_EQ(w4[0].first, 0u);
  EXPECT_EQ(w4[0].last, 1u);
}

TEST(DescriptorSequencer, AMarkThatKeepsRisingIsLiveTrafficNotATail) {
  // While the owner drives in range its status overtakes descriptors in flight; they arrive, and
  // nothing is asked for.
  DescriptorSequencer s;
  std::vector<DescriptorIn> released;
  for (uint32_t i = 0; i < 10; ++i) {
    s.announce(1, i, seconds(i));
    EXPECT_TRUE(s.wanted(seconds(i), always, released).empty()) << "at " << i << " s";
    s.add(desc(1, i));
  }
  EXPECT_TRUE(s.wanted(seconds(30), always, released).empty());
  EXPECT_EQ(s.stats().sync_requests, 0u);
}

TEST(DescriptorSequencer, ATailOutOfReachWaitsAndOneNeverSentIsGivenUp) {
  DescriptorSequencer s;
  s.add(desc(2, 0));
  s.announce(2, 2, Nanos(0));
  std::vector<DescriptorIn> released;
  EXPECT_TRUE(s.wanted(
                   seconds(5), [](uint32_t) { return false; }, released)
                  .empty());
  for (int k = 0; k < 5; ++k) {
    EXPECT_EQ(s.wanted(seconds(10 + 2 * k), always, released).size(), 1u) << "attempt " << k;
  }
  EXPECT_TRUE(s.wanted(seconds(20), always, released).empty()) << "given up after five attempts";
  EXPECT_EQ(s.stats().gaps_skipped, 1u);
  EXPECT_EQ(s.stats().ids_skipped, 2u);
  EXPECT_EQ(s.next_expected(2), 3u);
  EXPECT_EQ(s.missing(), 0u);
  EXPECT_TRUE(s.add(desc(2, 1)).empty()) << "a skipped id arriving late is a duplicate";
}

}  // namespace
}  // namespace cdc::loops
