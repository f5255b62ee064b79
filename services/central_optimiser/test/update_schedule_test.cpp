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

}  // namespace
}  // namespace cdc::central
