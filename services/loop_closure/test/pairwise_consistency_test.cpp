// Which verified loops are published: own-robot loops that agree with the odometry, inter-robot
// loops from a consistent set broad enough, withdrawn when a larger set disagrees with them.
#include "cdc/loop_closure/pairwise_consistency.hpp"

#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <set>
#include <tuple>
#include <vector>

namespace cdc::loops {
namespace {

using test::planar;

// Each robot drives straight on, keyframes 2 m apart in its own odometry frame.
Eigen::Isometry3d pose(uint32_t k) { return planar(2.0 * k, 0, 0); }

graph::Matrix6d information(double sigma_m, double sigma_rad) {
  graph::Matrix6d info = graph::Matrix6d::Zero();
  info.diagonal() << Eigen::Vector3d::Constant(1 / (sigma_m * sigma_m)),
      Eigen::Vector3d::Constant(1 / (sigma_rad * sigma_rad));
  return info;
}

// Robot 1's odometry frame as robot 0's sees it: where the two started.
const Eigen::Isometry3d kStart = planar(0, 10, 0.2), kOtherStart = planar(5, 15, -0.3);

// A loop between robot 0's keyframe ka and robot 1's kb, for robot 1 started at `start`.
LoopOut inter(uint32_t ka, uint32_t kb, const Eigen::Isometry3d& start = kStart) {
  return LoopOut{0, ka, 1, kb, pose(ka).inverse() * start * pose(kb), information(0.01, 0.001), 0.05, false};
}

void add_odometry(PairwiseConsistency& pcm, uint32_t robot, uint32_t keyframes = 10) {
  for (uint32_t k = 0; k < keyframes; ++k)
    pcm.add_keyframe_odometry(robot, k, planar(2, 0, 0), information(0.02, 0.002));
}

using LoopKey = std::tuple<uint32_t, uint32_t, bool>;  // (keyframe_a, keyframe_b, withdrawn)
std::set<LoopKey> keys(const std::vector<LoopOut>& loops) {
  std::set<LoopKey> out;
  for (const LoopOut& l : loops) out.insert({l.keyframe_a, l.keyframe_b, l.withdrawn});
  return out;
}

TEST(PairwiseConsistency, InterRobotLoopsArePublishedOnceTheirSetRestsOnTwoKeyframesOfEachRobot) {
  PairwiseConsistency pcm{LoopParams{}};
  add_odometry(pcm, 0);
  add_odometry(pcm, 1);
  EXPECT_TRUE(pcm.add_loop(inter(2, 3)).empty()) << "one loop";
  EXPECT_TRUE(pcm.add_loop(inter(2, 4)).empty()) << "two, through one keyframe of robot 0";
  EXPECT_EQ(keys(pcm.add_loop(inter(5, 6))), (std::set<LoopKey>{{2, 3, false}, {2, 4, false}, {5, 6, false}}));
  EXPECT_TRUE(pcm.add_loop(inter(7, 7, kOtherStart)).empty()) << "inconsistent with the set";
  EXPECT_EQ(keys(pcm.add_loop(inter(8, 8))), (std::set<LoopKey>{{8, 8, false}}));
  EXPECT_EQ(pcm.stats().inter_proposed, 5u);
  EXPECT_EQ(pcm.stats().inter_accepted, 4u);
  EXPECT_EQ(pcm.stats().withdrawn, 0u);
}

TEST(PairwiseConsistency, ALargerConsistentSetWithdrawsTheLoopsOfASmallerOne) {
  PairwiseConsistency pcm{LoopParams{}};
  add_odometry(pcm, 0);
  add_odometry(pcm, 1);
  std::vector<LoopOut> events = pcm.add_loop(inter(1, 1));
  for (const LoopOut& l : pcm.add_loop(inter(3, 3))) events.push_back(l);
  ASSERT_EQ(keys(events), (std::set<LoopKey>{{1, 1, false}, {3, 3, false}}));
  events.clear();
  for (uint32_t k : {5u, 6u, 7u}) {
    for (const LoopOut& l : pcm.add_loop(inter(k, k, kOtherStart))) events.push_back(l);
  }
  EXPECT_EQ(keys(events), (std::set<LoopKey>{{1, 1, true}, {3, 3, true}, {5, 5, false}, {6, 6, false}, {7, 7, false}}));
  EXPECT_EQ(pcm.stats().withdrawn, 2u);
  EXPECT_EQ(pcm.stats().inter_accepted, 5u);
}

TEST(PairwiseConsistency, AnOwnLoopIsAcceptedWhenItAgreesWithTheRobotsOdometry) {
  PairwiseConsistency pcm{LoopParams{}};
  add_odometry(pcm, 0);
  const LoopOut good{0, 1, 0, 8, pose(1).inverse() * pose(8), information(0.01, 0.001), 0.05, false};
  ASSERT_EQ(pcm.add_loop(good).size(), 1u) << "at once, on its own";
  LoopOut bad = good;
  bad.keyframe_a = 2;
  bad.T_a_b = pose(2).inverse() * pose(8) * planar(5, 0, 0);
  EXPECT_TRUE(pcm.add_loop(bad).empty());
  EXPECT_EQ(pcm.stats().intra_accepted, 1u);
  EXPECT_EQ(pcm.stats().intra_inconsistent, 1u);
}

TEST(PairwiseConsistency, ARobotKnownOnlyByItsPoseHintsIsChainedThroughThem) {
  for (const bool hints : {false, true}) {
    PairwiseConsistency pcm{LoopParams{}};
    add_odometry(pcm, 0);
    if (hints) {
      for (uint32_t k = 0; k < 10; ++k) pcm.add_pose_hint(1, k, pose(k));
    }
    std::vector<LoopOut> events;
    for (const auto& [ka, kb] : {std::pair{2u, 3u}, std::pair{5u, 6u}, std::pair{8u, 9u}}) {
      for (const LoopOut& l : pcm.add_loop(inter(ka, kb))) events.push_back(l);
    }
    EXPECT_EQ(events.size(), hints ? 3u : 0u) << (hints ? "with" : "without") << " robot 1's pose hints";
  }
}

}  // namespace
}  // namespace cdc::loops
