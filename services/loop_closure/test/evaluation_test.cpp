// Precision and recall against ground truth (evaluation.hpp), shared by cdc-loops and the benchmark.
#include "cdc/loop_closure/evaluation.hpp"

#include <gtest/gtest.h>

namespace cdc::loops {
namespace {

Eigen::Isometry3d at(double x) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = x;
  return T;
}

// Robot 0 drives 0..9 along x; robot 1 then passes its keyframes 2 and 7 (revisits of 0/2 and 0/7).
std::vector<TruthKeyframe> two_robots() {
  std::vector<TruthKeyframe> order;
  for (uint32_t i = 0; i < 10; ++i) order.push_back({0, i, at(10.0 * i)});
  order.push_back({1, 0, at(500.0)});
  order.push_back({1, 1, at(20.5)});
  order.push_back({1, 2, at(70.5)});
  return order;
}

LoopOut loop(uint32_t ra, uint32_t ka, uint32_t rb, uint32_t kb, const std::vector<TruthKeyframe>& order) {
  auto find = [&](uint32_t r, uint32_t k) {
    for (const auto& t : order) {
      if (t.robot == r && t.id == k) return t.T_world;
    }
    return Eigen::Isometry3d::Identity();
  };
  LoopOut l;
  l.robot_a = ra;
  l.keyframe_a = ka;
  l.robot_b = rb;
  l.keyframe_b = kb;
  l.T_a_b = find(ra, ka).inverse() * find(rb, kb);
  return l;
}

TEST(Evaluation, ALoopRecallsItsLaterKeyframeWhicheverWayRoundItIsGiven) {
  const auto order = two_robots();
  EvaluationOptions o;
  o.exclude_recent = 5;
  // One loop with the earlier keyframe first, one with the later keyframe first (as a robot's
  // service publishes loops with its own keyframe first).
  const LoopEvaluation ev = evaluate_loops(order, {loop(0, 2, 1, 1, order), loop(1, 2, 0, 7, order)}, o);
  EXPECT_EQ(ev.true_positives, 2u);
  EXPECT_EQ(ev.revisits, 2u);
  EXPECT_EQ(ev.recalled, 2u) << "both revisits of robot 1 are closed";
  EXPECT_TRUE(ev.missed.empty());
  EXPECT_DOUBLE_EQ(ev.recall(), 1.0);
}

TEST(Evaluation, AWrongLoopCountsAsFalseAndRecallsNothing) {
  const auto order = two_robots();
  EvaluationOptions o;
  o.exclude_recent = 5;
  LoopOut wrong = loop(1, 1, 0, 2, order);
  wrong.T_a_b.translation().x() += 3.0;  // 3 m off
  const LoopEvaluation ev = evaluate_loops(order, {wrong}, o);
  EXPECT_EQ(ev.true_positives, 0u);
  EXPECT_EQ(ev.false_inter, 1u);
  EXPECT_EQ(ev.recalled, 0u);
  ASSERT_EQ(ev.missed.size(), 2u);
  EXPECT_EQ(ev.missed[0], std::make_pair(1u, 1u));
}

}  // namespace
}  // namespace cdc::loops
