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

TEST(LocalGraph, KnowsItsGroupThroughLoopsItsPeersRelay) {
  // Robot 1 has loops with robots 0 and 2 (and one within itself); robot 2 relays its loop with
  // robot 3, robot 0 one with robot 2 that a withdrawal retracts.
  LocalGraph g(1);
  g.add_keyframe(keyframe_at(4, 0));
  g.add_loop(loop(0, 3, 1, 4));
  g.add_loop(loop(1, 6, 2, 2));
  g.add_loop(loop(1, 1, 1, 9));
  EXPECT_EQ(g.group(), (std::set<uint32_t>{0, 2}));
  EXPECT_FALSE(g.add_group_loop(loop(1, 7, 3, 1))) << "a loop touching robot 1 comes from the loop closures";
  EXPECT_TRUE(g.add_group_loop(loop(2, 5, 3, 1)));
  const LoopRecord relayed = loop(0, 8, 2, 8);
  EXPECT_TRUE(g.add_group_loop(relayed));
  EXPECT_FALSE(g.add_group_loop(relayed)) << "a loop held already";
  EXPECT_EQ(g.group(), (std::set<uint32_t>{0, 2, 3})) << "robot 3 is reached through robot 2";
  EXPECT_EQ(g.inter_robot_loops().size(), 4u);
  LoopRecord withdrawal = loop(0, 8, 2, 8, true);
  g.add_group_loop(withdrawal);
  EXPECT_EQ(g.inter_robot_loops().size(), 3u) << "a withdrawn loop still counts";

  // Every robot of the group gets every own keyframe an inter-robot loop touches; robot 1 relays
  // its loops with higher robots to the others (robot 0 relays their loops with robot 1).
  const std::set<uint32_t> own{4, 6};
  EXPECT_EQ(g.group_separator_ids(), (std::map<uint32_t, std::set<uint32_t>>{{0, own}, {2, own}, {3, own}}));
  const auto relay = g.loops_to_relay();
  ASSERT_EQ(relay.count(0), 1u);
  ASSERT_EQ(relay.at(0).size(), 1u);
  EXPECT_EQ(relay.at(0)[0].robot_b, 2u);
  EXPECT_EQ(relay.at(3).size(), 1u);
  EXPECT_EQ(relay.count(2), 0u) << "robot 2 is an end of robot 1's only loop with a higher robot";
}

}  // namespace
}  // namespace cdc::peer
