// The end of a mission with a final rendezvous, driven by hand with made-up instants.
#include "rendezvous.hpp"

#include <gtest/gtest.h>

namespace cdc::launch {
namespace {

using namespace std::chrono_literals;
using Clock = Rendezvous::Clock;

const Clock::time_point kStart = Clock::time_point{} + 1000s;

TEST(Rendezvous, EndsOnceEveryoneIsInAndCaughtUpForTheSettlingTime) {
  Rendezvous w(kStart, 5s, 60s);
  EXPECT_FALSE(w.update({1}, {0, 1}, kStart + 1s));
  EXPECT_FALSE(w.update({}, {1}, kStart + 3s));  // all rejoined at 3 s
  EXPECT_FALSE(w.update({}, {}, kStart + 4s));   // all caught up at 4 s
  EXPECT_FALSE(w.update({}, {}, kStart + 8s));   // 4 s since both: not yet
  EXPECT_TRUE(w.update({}, {}, kStart + 9s));
  EXPECT_DOUBLE_EQ(w.waited_s(), 3.0);
  ASSERT_TRUE(w.caught_up_s().has_value());
  EXPECT_DOUBLE_EQ(*w.caught_up_s(), 4.0);
  EXPECT_TRUE(w.not_rejoined().empty());
  EXPECT_TRUE(w.loop_closure_busy().empty());
}

TEST(Rendezvous, ARobotDroppingOutRestartsTheSettlingTime) {
  Rendezvous w(kStart, 5s, 60s);
  EXPECT_FALSE(w.update({}, {}, kStart + 1s));
  EXPECT_FALSE(w.update({2}, {}, kStart + 4s));  // its lease lapsed after all
  EXPECT_FALSE(w.update({}, {}, kStart + 6s));   // back in at 6 s
  EXPECT_FALSE(w.update({}, {}, kStart + 10s));
  EXPECT_TRUE(w.update({}, {}, kStart + 11s));
  EXPECT_DOUBLE_EQ(w.waited_s(), 6.0);
  EXPECT_DOUBLE_EQ(*w.caught_up_s(), 1.0);
}

TEST(Rendezvous, GivesUpAtTheLimitAndSaysWhoWasMissing) {
  Rendezvous w(kStart, 5s, 35s);
  EXPECT_FALSE(w.update({1}, {2}, kStart + 10s));
  EXPECT_FALSE(w.update({1}, {2}, kStart + 34s));
  EXPECT_TRUE(w.update({1}, {2}, kStart + 35s));
  EXPECT_DOUBLE_EQ(w.waited_s(), 35.0);  // never all in: until the end
  EXPECT_FALSE(w.caught_up_s().has_value());
  EXPECT_EQ(w.not_rejoined(), std::vector<uint32_t>{1});
  EXPECT_EQ(w.loop_closure_busy(), std::vector<uint32_t>{2});
}

}  // namespace
}  // namespace cdc::launch
