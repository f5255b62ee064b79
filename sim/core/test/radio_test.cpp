#include "cdc/sim/radio.hpp"

#include <gtest/gtest.h>

namespace cdc::sim {
namespace {

TEST(Radio, LinksFollowDistanceAndTheSmallerRange) {
  // Node 1 drives away from node 0 along x at 10 m/s and back; node 0 stays.
  std::vector<RadioNode> nodes = {
      {0, 200, [](double) { return Eigen::Vector3d::Zero(); }},
      {1, 100, [](double t) { return Eigen::Vector3d(t < 20 ? 10 * t : 400 - 10 * t, 0, 0); }},
  };
  const auto tl = radio_timeline(nodes, 0, 40, RadioOptions{});
  ASSERT_EQ(tl.size(), 401u);
  EXPECT_TRUE(tl[100].in_range);   // t = 10 s: 100 m, exactly the smaller range
  EXPECT_FALSE(tl[101].in_range);  // 101 m
  EXPECT_NEAR(tl[90].loss, 0.3 * (90.0 - 80.0) / 20.0, 1e-12);
  EXPECT_DOUBLE_EQ(tl[50].loss, 0.0);
  const auto periods = out_of_range_periods(tl);
  ASSERT_EQ(periods.size(), 1u);
  EXPECT_NEAR(periods[0].start, 10.1, 1e-9);
  EXPECT_NEAR(periods[0].end, 30.0, 1e-9);
  EXPECT_EQ(radio_csv(tl).substr(0, 29), "t,a,b,in_range,distance,loss\n");
}

}  // namespace
}  // namespace cdc::sim
