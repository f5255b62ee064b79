#include "cdc/central_optimiser/update_schedule.hpp"

#include <gtest/gtest.h>

namespace cdc::central {
namespace {

using std::chrono::milliseconds;

TEST(UpdateSchedule, OptimisesWhenChangedOrUnsettledAndThePeriodHasPassed) {
  UpdateSchedule s(milliseconds(100), milliseconds(2000));
  const auto t0 = UpdateSchedule::Clock::now();
  EXPECT_FALSE(s.update_due(false, true, t0)) << "nothing changed, graph settled";
  EXPECT_TRUE(s.update_due(true, true, t0));
  EXPECT_TRUE(s.update_due(false, false, t0));
  EXPECT_TRUE(s.updated(true, t0));
  EXPECT_FALSE(s.update_due(true, true, t0 + milliseconds(99)));
  EXPECT_TRUE(s.update_due(true, true, t0 + milliseconds(100)));
  EXPECT_EQ(s.updates(), 1u);
}

TEST(UpdateSchedule, HoldsResultsOfAnUnsettledGraphUntilTheLastOnesGetOld) {
  UpdateSchedule s(milliseconds(100), milliseconds(2000));
  const auto t0 = UpdateSchedule::Clock::now();
  EXPECT_TRUE(s.updated(true, t0));
  EXPECT_FALSE(s.updated(false, t0 + milliseconds(100)));
  EXPECT_FALSE(s.updated(false, t0 + milliseconds(1999)));
  EXPECT_TRUE(s.updated(false, t0 + milliseconds(2000))) << "the last results are 2 s old";
  EXPECT_FALSE(s.updated(false, t0 + milliseconds(2100)));
  EXPECT_TRUE(s.updated(true, t0 + milliseconds(2200))) << "a settled graph always goes out";
  EXPECT_EQ(s.updates(), 6u);
  EXPECT_EQ(s.unsettled_updates(), 4u);
  EXPECT_EQ(s.results_held(), 3u);
}

TEST(UpdateSchedule, TheFirstUnsettledResultsGoOut) {
  UpdateSchedule s(milliseconds(100), milliseconds(2000));
  EXPECT_TRUE(s.updated(false, UpdateSchedule::Clock::now())) << "nothing was published yet";
}

TEST(ResultPacer, KeepsEachRobotsPosesWithinTheRate) {
  ResultPacer p(2, 1000.0);  // poses per second per robot
  const auto t0 = ResultPacer::Clock::now();
  EXPECT_FALSE(p.due(0, t0)) << "nothing to send yet";
  p.updated();
  EXPECT_TRUE(p.due(0, t0));
  EXPECT_TRUE(p.due(1, t0));
  p.sent(0, 500, t0);  // robot 0's next result waits 0.5 s
  p.sent(1, 100, t0);  // robot 1's 0.1 s
  EXPECT_FALSE(p.due(0, t0 + milliseconds(600))) << "sent, nothing new";
  p.updated();
  p.updated();
  EXPECT_FALSE(p.due(0, t0 + milliseconds(499)));
  EXPECT_TRUE(p.due(0, t0 + milliseconds(500)));
  EXPECT_TRUE(p.due(1, t0 + milliseconds(100)));
  EXPECT_EQ(p.merged(), 2u) << "the second update's results replace the first's, per robot";
  EXPECT_FALSE(p.due(2, t0)) << "no such robot";
}

TEST(ResultPacer, ARateOfZeroSendsEveryUpdate) {
  ResultPacer p(1, 0.0);
  const auto t0 = ResultPacer::Clock::now();
  p.updated();
  p.sent(0, 1'000'000, t0);
  p.updated();
  EXPECT_TRUE(p.due(0, t0));
  EXPECT_EQ(p.merged(), 0u);
}

}  // namespace
}  // namespace cdc::central
