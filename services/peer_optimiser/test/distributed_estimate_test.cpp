#include "cdc/peer_optimiser/distributed_estimate.hpp"
#include "peer_test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace cdc::peer {
namespace {

// Keyframes 0..count-1 of `robot`, one metre apart along x in its odometry frame.
LocalGraph straight_line(uint32_t robot, uint32_t count) {
  LocalGraph g(robot);
  for (uint32_t id = 0; id < count; ++id) {
    OwnKeyframe kf;
    kf.id = id;
    kf.T_odom = pose_at(id);
    kf.T_prev = pose_at(id > 0 ? 1.0 : 0.0);
    g.add_keyframe(kf);
  }
  return g;
}

// A loop from robot_a's keyframe_a to robot_b's keyframe_b measuring T_a_b.
LoopRecord loop(uint32_t robot_a, uint32_t keyframe_a, uint32_t robot_b, uint32_t keyframe_b,
                const Eigen::Isometry3d& T_a_b) {
  LoopRecord l;
  l.robot_a = robot_a;
  l.keyframe_a = keyframe_a;
  l.robot_b = robot_b;
  l.keyframe_b = keyframe_b;
  l.T_a_b = T_a_b;
  return l;
}

double x_of(const DistributedEstimate& e, uint32_t id) { return e.poses().at(id).translation().x(); }

TEST(DistributedEstimate, SeedsFromTheCentralThenItsPredecessorThenTheWorldTransform) {
  const LocalGraph g = straight_line(1, 4);
  DistributedEstimate e(config(1));
  e.seed(g, {{1, pose_at(10)}}, pose_at(100));
  ASSERT_EQ(e.poses().size(), 4u);
  EXPECT_EQ(x_of(e, 0), 100.0) << "no central pose, no predecessor: T_world_robot times its odometry";
  EXPECT_EQ(x_of(e, 1), 10.0) << "the central's pose";
  EXPECT_EQ(x_of(e, 2), 11.0) << "its predecessor's estimate times its odometry";
  EXPECT_EQ(x_of(e, 3), 12.0);
  e.seed(g, {{2, pose_at(-5)}}, std::nullopt);
  EXPECT_EQ(x_of(e, 2), 11.0) << "a keyframe with an estimate keeps it";
}

TEST(DistributedEstimate, ANewKeyframeFollowsItsPredecessor) {
  LocalGraph g = straight_line(1, 4);
  DistributedEstimate e(config(1));
  e.seed(g, {}, pose_at(20));
  OwnKeyframe next = g.keyframes().at(3);
  next.id = 4;
  next.T_odom = pose_at(4);
  e.extend(next);
  EXPECT_EQ(x_of(e, 4), 24.0);
  next.id = 9;  // no predecessor with an estimate
  e.extend(next);
  EXPECT_EQ(e.poses().count(9), 0u);
  e.clear();
  EXPECT_TRUE(e.poses().empty());
}

TEST(DistributedEstimate, TheLowestRobotKeepsItsOdometryFrame) {
  const LocalGraph g = straight_line(0, 5);
  DistributedEstimate e(config(0));
  const auto T_world_robot = e.round(g, {}, std::nullopt);
  ASSERT_TRUE(T_world_robot);
  EXPECT_LT((T_world_robot->matrix() - Eigen::Matrix4d::Identity()).norm(), 1e-6);
  for (uint32_t id = 0; id < 5; ++id) EXPECT_NEAR(x_of(e, id), id, 1e-6);
  EXPECT_FALSE(e.placed_by_peers());
  EXPECT_EQ(e.rounds(), 1u);
}

TEST(DistributedEstimate, PlacesTheRobotThroughALowerPeersSeparatorPose) {
  // Robot 1's keyframe 1 sees robot 0's keyframe 5 two metres ahead and turned by 0.5 rad.
  LocalGraph g = straight_line(1, 3);
  LoopRecord l = loop(1, 1, 0, 5, pose_at(2, 0, 0.5));
  g.add_loop(l);
  const Eigen::Isometry3d T_world_0_5 = pose_at(40, 30, 1.0);
  g.on_separator(0, {{5, T_world_0_5}});
  DistributedEstimate e(config(1));
  ASSERT_TRUE(e.round(g, {}, std::nullopt));
  EXPECT_TRUE(e.placed_by_peers());
  const Eigen::Isometry3d want = T_world_0_5 * l.T_a_b.inverse();
  EXPECT_LT((e.poses().at(1).matrix() - want.matrix()).norm(), 1e-6);

  // A separator pose of a higher robot does not place it: that robot is placed through this one.
  LocalGraph alone = straight_line(1, 3);
  l.robot_b = 2;
  alone.add_loop(l);
  alone.on_separator(2, {{5, T_world_0_5}});
  DistributedEstimate e2(config(1));
  e2.round(alone, {}, std::nullopt);
  EXPECT_FALSE(e2.placed_by_peers());
}

TEST(DistributedEstimate, EachRoundMovesRelaxationOfTheWayToItsSolution) {
  // Keyframe 1 anchored by the central at x = 3, keyframe 0 starting at 0: the solution puts
  // keyframe 0 one metre behind it, at 2, and a round with relaxation 0.5 takes it half way.
  const LocalGraph g = straight_line(0, 2);
  PeerConfig c = config(0);
  c.relaxation = 0.5;
  DistributedEstimate e(c);
  e.round(g, {{1, pose_at(3)}}, std::nullopt);
  EXPECT_NEAR(x_of(e, 0), 1.0, 1e-4);
  EXPECT_NEAR(x_of(e, 1), 3.0, 1e-4);
  e.round(g, {{1, pose_at(3)}}, std::nullopt);
  EXPECT_NEAR(x_of(e, 0), 1.5, 1e-4);
  EXPECT_EQ(e.rounds(), 2u);
}

TEST(DistributedEstimate, TheCoarseStepMovesAHigherRobotAndTheGaugeKeepsItsFirstKeyframe) {
  // Robot 0's keyframe 4 sees robot 1's keyframe 2 one metre ahead, which robot 1 reports 3 m and a
  // tenth of a radian off: the coarse step moves robot 1 onto the loop and robot 0 stays, its first
  // keyframe at its odometry pose.
  LocalGraph g = straight_line(0, 5);
  const LoopRecord l = loop(0, 4, 1, 2, pose_at(1));
  g.add_loop(l);
  g.on_separator(1, {{2, pose_at(8, 0, 0.1)}});
  g.on_coarse_view(1, 1, true);  // robot 1 has this one loop and runs the coarse step too
  DistributedEstimate e(config(0));
  ASSERT_TRUE(e.round(g, {}, std::nullopt));
  EXPECT_EQ(e.coarse_steps(), 1u);
  EXPECT_LT((e.poses().at(0).matrix() - pose_at(0).matrix()).norm(), 1e-9) << "the gauge's first keyframe moved";
  for (uint32_t id = 0; id < 5; ++id) EXPECT_NEAR(x_of(e, id), id, 1e-3) << "robot 0 was pulled to robot 1";

  // Robot 1 in the same group is placed by the coarse step (robot 0 holds still in it).
  LocalGraph g1 = straight_line(1, 3);
  g1.add_loop(l);
  g1.on_separator(0, {{4, pose_at(4)}});
  g1.on_coarse_view(0, 1, true);
  PeerConfig c1 = config(1);
  c1.relaxation = 1.0;
  DistributedEstimate e1(c1);
  ASSERT_TRUE(e1.round(g1, {}, pose_at(100, 50, 1.0)));
  EXPECT_TRUE(e1.placed_by_peers());
  EXPECT_LT((e1.poses().at(2).matrix() - pose_at(5).matrix()).norm(), 1e-6);

  PeerConfig without = config(0);
  without.coarse_step = false;
  DistributedEstimate e2(without);
  e2.round(g, {}, std::nullopt);
  EXPECT_EQ(e2.coarse_steps(), 0u);
  EXPECT_GT(x_of(e2, 4), 4.1) << "block solves alone pull the lowest robot toward its peer";

  // While robot 1 has a loop robot 0 does not hold, or does not run the coarse step (the central's
  // estimate anchors it), their coarse problems would differ: robot 0 runs none.
  g.on_coarse_view(1, 2, true);
  DistributedEstimate e3(config(0));
  e3.round(g, {}, std::nullopt);
  EXPECT_EQ(e3.coarse_steps(), 0u);
  g.on_coarse_view(1, 1, false);
  e3.round(g, {}, std::nullopt);
  EXPECT_EQ(e3.coarse_steps(), 0u);
}

// A 20 m square lap driven twice (keyframes 2 m apart), odometry drifting in yaw, true loops between
// the laps and one wrong loop that puts keyframe 25 at keyframe 5's place turned by 90 degrees.
struct SquareLaps {
  LocalGraph graph{0};
  std::vector<Eigen::Isometry3d> truth;
};

SquareLaps square_laps(bool wrong_loop) {
  SquareLaps laps;
  for (uint32_t id = 0; id < 80; ++id) {
    const uint32_t side = (id / 10) % 4, step = id % 10;
    const double yaw = M_PI / 2 * side;
    const Eigen::Vector2d corner[4] = {{0, 0}, {20, 0}, {20, 20}, {0, 20}};
    const Eigen::Vector2d p = corner[side] + 2.0 * step * Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
    laps.truth.push_back(pose_at(p.x(), p.y(), yaw));
  }
  Eigen::Isometry3d odom = Eigen::Isometry3d::Identity();
  for (uint32_t id = 0; id < 80; ++id) {
    OwnKeyframe kf;
    kf.id = id;
    kf.T_prev = id == 0 ? Eigen::Isometry3d::Identity()
                        : laps.truth[id - 1].inverse() * laps.truth[id] * pose_at(0, 0, 0.004);  // drifts
    odom = odom * kf.T_prev;
    kf.T_odom = odom;
    kf.information = Matrix6d::Identity() * 100.0;
    laps.graph.add_keyframe(kf);
  }
  uint32_t seq = 0;
  for (uint32_t id = 40; id < 80; id += 5) {
    laps.graph.add_loop({0, 3, seq++, 0, id - 40, 0, id, false, laps.truth[id - 40].inverse() * laps.truth[id],
                         Matrix6d::Identity() * 100.0});
  }
  if (wrong_loop) {
    laps.graph.add_loop({0, 3, seq++, 0, 5, 0, 25, false, pose_at(0, 0, M_PI / 2), Matrix6d::Identity() * 100.0});
  }
  return laps;
}

double worst_error(const DistributedEstimate& e, const std::vector<Eigen::Isometry3d>& truth) {
  double worst = 0;
  for (const auto& [id, T] : e.poses()) worst = std::max(worst, (T.translation() - truth[id].translation()).norm());
  return worst;
}

TEST(DistributedEstimate, GncHoldsAWrongOwnLoopOut) {
  const SquareLaps clean = square_laps(false), spoiled = square_laps(true);
  auto run = [](const SquareLaps& laps, double threshold) {
    PeerConfig c = config(0);
    c.own_loop_gnc_threshold = threshold;
    DistributedEstimate e(c);
    for (int round = 0; round < 30; ++round) e.round(laps.graph, {}, std::nullopt);
    return std::make_pair(worst_error(e, laps.truth), e.own_loops_held_out());
  };
  const auto [clean_error, clean_out] = run(clean, 16.81);
  EXPECT_EQ(clean_out, 0u);
  const auto [robust_error, robust_out] = run(spoiled, 16.81);
  EXPECT_EQ(robust_out, 1u);
  EXPECT_NEAR(robust_error, clean_error, 0.01);
  const auto [plain_error, plain_out] = run(spoiled, 0.0);
  EXPECT_EQ(plain_out, 0u);
  EXPECT_GT(plain_error, clean_error + 1.0) << "the wrong loop bends the lap without GNC";
}

TEST(DistributedEstimate, ARoundWithoutKeyframesGivesNothing) {
  DistributedEstimate e(config(1));
  EXPECT_FALSE(e.round(LocalGraph(1), {}, std::nullopt));
  EXPECT_EQ(e.rounds(), 0u);
}

}  // namespace
}  // namespace cdc::peer
