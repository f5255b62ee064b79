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

#include "cdc/sim/missions.hpp"

namespace cdc::sim {
namespace {

TEST(Missions, RaysLeaveAndReenterTheStartsRangeEveryLap) {
  MissionOptions o;
  o.pattern = MissionPattern::kRays;
  o.robots = 3;
  o.duration_s = 200;
  o.speed_mps = 5;
  o.size_m = 150;
  const auto robots = procedural_mission(o);
  ASSERT_EQ(robots.size(), 3u);
  for (const auto& r : robots) {
    ASSERT_EQ(r.size(), 2001u);
    // Smooth ground-vehicle motion: 0.5 m per 0.1 s step, heading changes at most v/R dt.
    for (size_t i = 1; i < r.size(); ++i) {
      EXPECT_NEAR((r[i].pose.translation() - r[i - 1].pose.translation()).norm(), 0.5, 0.01);
      const double dh = Eigen::AngleAxisd(r[i - 1].pose.rotation().transpose() * r[i].pose.rotation()).angle();
      EXPECT_LE(dh, 5.0 / 8.0 * 0.1 + 1e-9);
    }
  }
  // A central at the start with a 100 m range: every robot leaves it at least twice.
  std::vector<RadioNode> nodes{{200, 100, [](double) { return Eigen::Vector3d::Zero(); }}};
  for (uint32_t k = 0; k < 3; ++k) {
    const auto* traj = &robots[k];
    nodes.push_back({k, 100, [traj](double t) {
                       const size_t i = std::min(traj->size() - 1, static_cast<size_t>(std::llround(t * 10)));
                       return Eigen::Vector3d((*traj)[i].pose.translation());
                     }});
  }
  const auto periods = out_of_range_periods(radio_timeline(nodes, 0, 200, RadioOptions{}));
  for (uint32_t k = 0; k < 3; ++k) {
    const auto n = std::count_if(periods.begin(), periods.end(), [&](const auto& p) { return p.a == k && p.b == 200; });
    EXPECT_GE(n, 2) << "robot " << k;
  }
}

TEST(Missions, LoopsAndCrossingsAreBuilt) {
  for (const char* name : {"loops", "crossing"}) {
    MissionOptions o;
    o.pattern = *parse_pattern(name);
    o.duration_s = 30;
    const auto r = procedural_mission(o);
    ASSERT_EQ(r.size(), 3u) << name;
    EXPECT_EQ(r[0].size(), 301u);
  }
  EXPECT_FALSE(parse_pattern("spiral"));
}

}  // namespace
}  // namespace cdc::sim
