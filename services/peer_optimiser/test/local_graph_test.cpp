#include "cdc/peer_optimiser/local_graph.hpp"
#include "peer_test_support.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>

namespace cdc::peer {
namespace {

OwnKeyframe keyframe_at(uint32_t id, double x) {
  OwnKeyframe kf;
  kf.id = id;
  kf.T_odom = pose_at(x);
  kf.T_prev = pose_at(id > 0 ? 1.0 : 0.0);
  return kf;
}

LoopRecord loop(uint32_t robot_a, uint32_t keyframe_a, uint32_t robot_b, uint32_t keyframe_b, bool withdrawn = false) {
  static uint32_t seq = 0;
  return LoopRecord{.sender = robot_a,
                    .seq = seq++,
                    .robot_a = robot_a,
                    .keyframe_a = keyframe_a,
                    .robot_b = robot_b,
                    .keyframe_b = keyframe_b,
                    .withdrawn = withdrawn};
}

TEST(LocalGraph, KeepsEachKeyframeAndLoopOnce) {
  LocalGraph g(1);
  EXPECT_FALSE(g.newest_id());
  EXPECT_TRUE(g.add_keyframe(keyframe_at(0, 0)));
  EXPECT_TRUE(g.add_keyframe(keyframe_at(1, 1)));
  EXPECT_FALSE(g.add_keyframe(keyframe_at(1, 5))) << "a keyframe already held";
  EXPECT_EQ(g.keyframes().at(1).T_odom.translation().x(), 1.0);
  EXPECT_EQ(g.newest_id(), 1u);

  LoopRecord l = loop(0, 3, 1, 1);
  l.sender_incarnation = 3;
  EXPECT_TRUE(g.add_loop(l));
  EXPECT_FALSE(g.add_loop(l)) << "the same sender, incarnation and seq";
  l.sender_incarnation = 4;  // the sender restarted: a new loop
  EXPECT_TRUE(g.add_loop(l));
  EXPECT_EQ(g.loops().size(), 2u);
}

TEST(LocalGraph, EachPeerNeedsTheOwnKeyframesItsLoopsTouch) {
  LocalGraph g(1);
  g.add_loop(loop(1, 4, 0, 9));
  g.add_loop(loop(2, 3, 1, 6));
  g.add_loop(loop(1, 5, 1, 2));        // within the robot: no peer needs it
  g.add_loop(loop(1, 8, 0, 1, true));  // withdrawn
  g.add_loop(loop(0, 2, 2, 7));        // not touching this robot
  const auto wanted = g.separator_ids();
  ASSERT_EQ(wanted.size(), 2u);
  EXPECT_EQ(wanted.at(0), std::set<uint32_t>{4});
  EXPECT_EQ(wanted.at(2), std::set<uint32_t>{6});
}

TEST(LocalGraph, IsTheLowestOfItsGroupUntilALoopTiesItToALowerRobot) {
  LocalGraph g(1);
  g.add_loop(loop(1, 4, 2, 9));
  g.add_loop(loop(0, 2, 2, 7));        // between two other robots
  g.add_loop(loop(0, 1, 1, 8, true));  // withdrawn
  EXPECT_TRUE(g.lowest_in_group());
  g.add_loop(loop(1, 5, 0, 3));
  EXPECT_FALSE(g.lowest_in_group());
}

TEST(LocalGraph, TheWorldTransformOfASolutionIsItsRigidFitToTheOdometry) {
  LocalGraph g(1);
  const Eigen::Isometry3d T_world_robot = pose_at(10, -4, 0.3);
  KeyframePoses solution;
  for (uint32_t id = 0; id < 6; ++id) {
    OwnKeyframe kf = keyframe_at(id, id);
    kf.T_odom = pose_at(id, 0.2 * id * id, 0.1 * id);  // a curve, so that the fit is well posed
    g.add_keyframe(kf);
    solution.emplace_back(id, T_world_robot * kf.T_odom);
  }
  solution.emplace_back(42, pose_at(1e3));  // not one of its keyframes: ignored
  const auto fitted = g.world_transform_of(solution);
  ASSERT_TRUE(fitted);
  EXPECT_LT((fitted->matrix() - T_world_robot.matrix()).norm(), 1e-9);
}

TEST(LocalGraph, ItsGraphHoldsTheEstimateTheOdometryAndTheLoopsWithBothEnds) {
  LocalGraph g(1);
  for (uint32_t id = 0; id < 3; ++id) g.add_keyframe(keyframe_at(id, id));
  g.on_separator(0, {{9, pose_at(50)}});
  g.add_loop(loop(1, 2, 0, 9));        // both ends known
  g.add_loop(loop(1, 1, 0, 5));        // no separator pose for robot 0's keyframe 5
  g.add_loop(loop(1, 0, 0, 9, true));  // withdrawn
  const graph::PoseGraph pg = g.graph({{1, pose_at(7)}});
  ASSERT_EQ(pg.poses.size(), 4u);
  EXPECT_EQ(pg.poses.at(graph::make_key(1, 0)).translation().x(), 0.0) << "no estimate: odometry";
  EXPECT_EQ(pg.poses.at(graph::make_key(1, 1)).translation().x(), 7.0) << "the estimate";
  EXPECT_EQ(pg.poses.at(graph::make_key(0, 9)).translation().x(), 50.0) << "the separator pose";
  EXPECT_EQ(pg.count(graph::FactorKind::kOdometry), 2u);
  EXPECT_EQ(pg.count(graph::FactorKind::kLoop), 1u);
}

}  // namespace
}  // namespace cdc::peer
