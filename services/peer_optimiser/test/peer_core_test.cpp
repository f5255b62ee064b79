#include "cdc/peer_optimiser/peer_core.hpp"
#include "cdc/geometry/alignment.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"
#include "peer_test_support.hpp"
#include "swarm_stream.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <optional>

namespace cdc::peer {
namespace {

using namespace std::chrono_literals;

// A robot with keyframes 0..count-1, joined to a central that holds them all (its estimate the
// truth): steps until CENTRALIZED and returns the time reached.
Nanos join_central(PeerCore& core, const test::SwarmStream& s, uint32_t robot, uint32_t count, Nanos until) {
  for (uint32_t id = 0; id < count; ++id) {
    core.add_keyframe(kf_from(s.keyframes[robot][id]), 0s);
  }
  core.on_central_result(central_for(s, robot, count - 1, Eigen::Isometry3d::Identity()));
  Nanos t = 0s;
  for (; t <= until; t += 50ms) {
    core.step(t, true);
  }
  return t;
}

// Robot 1 with keyframes 0..59 joins the central, loses its lease, makes keyframes 60..79 in
// DISTRIBUTED mode and comes back: returns the time of its switch to CENTRALIZED (none: it did not).
std::optional<Nanos> cut_and_rejoin(PeerCore& core, const test::SwarmStream& s) {
  Nanos t = join_central(core, s, 1, 60, 1500ms);
  if (core.mode() != Mode::kCentralized || !core.step(t += 50ms, false).transition) return std::nullopt;
  for (uint32_t id = 60; id < 80; ++id) {
    core.add_keyframe(kf_from(s.keyframes[1][id]), t);
    core.step(t += 100ms, false);
  }
  for (int i = 0; i < 40; ++i) {
    const auto out = core.step(t += 50ms, true);
    if (out.transition && out.transition->to == Mode::kCentralized) return t;
  }
  return std::nullopt;
}

// Keyframes without a corrected pose follow their odometry from the nearest corrected one before
// them (the first corrected one when none is before them).
TEST(PeerCore, CompletesWorldPosesFromTheNearestCorrectedKeyframe) {
  auto at = [](double x) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = x;
    return T;
  };
  const std::map<uint32_t, Eigen::Isometry3d> T_odom = {{0, at(0)}, {1, at(1)}, {2, at(2)}, {3, at(3)}, {4, at(4)}};
  const std::map<uint32_t, Eigen::Isometry3d> corrected = {{1, at(11)}, {3, at(23)}};
  const auto w = complete_world_poses(T_odom, corrected);
  ASSERT_EQ(w.size(), 5u);
  const std::vector<double> want = {10, 11, 12, 23, 24};
  for (uint32_t id = 0; id < 5; ++id) EXPECT_NEAR(w.at(id).translation().x(), want[id], 1e-12) << id;
  EXPECT_NEAR(complete_world_poses(T_odom, {}).at(4).translation().x(), 4.0, 1e-12);
}

TEST(PeerCore, RelaysTheCentralWithBoundedStepsAndConverges) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  Nanos t = join_central(core, s, 1, 50, 1s);
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  // The central's estimate moves by 2 m and 5 deg: the published correction follows in bounded steps.
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.translation() = Eigen::Vector3d(2, 0, 0);
  offset.linear() = geometry::from_rpy(0, 0, 5 * M_PI / 180);
  const CentralResult moved = central_for(s, 1, 49, offset);
  core.on_central_result(moved);
  Eigen::Isometry3d prev = core.step(t += 50ms, true).correction->T_world_robot;
  int steps = 0;
  for (; steps < 400; ++steps) {
    const auto out = core.step(t += 50ms, true);
    const Eigen::Isometry3d cur = out.correction->T_world_robot;
    EXPECT_LE((cur.translation() - prev.translation()).norm(), 0.1 + 1e-9);
    EXPECT_LE(geometry::rotation_angle(prev.rotation().transpose() * cur.rotation()), 0.01 + 1e-9);
    prev = cur;
    if ((cur.matrix() - moved.T_world_robot.matrix()).norm() < 1e-9) {
      break;
    }
  }
  EXPECT_LT(steps, 400) << "the correction never reached the central's estimate";
  EXPECT_GT(steps, 5) << "a 2 m / 5 deg change cannot be taken in a few bounded steps";
}

// While T_world_robot takes a new solution in bounded steps, the poses sent with it are in its frame:
// the front-end's keyframe in its odometry frame (T_world_robot^-1 * pose) is the new solution's own
// at every step, not a mix of the new poses and a frame still on its way.
TEST(PeerCore, TheCorrectionsPosesAgreeWithItsWorldTransformAtEveryStep) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  Nanos t = join_central(core, s, 1, 50, 1s);
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  // A new solution that turns the robot's whole trajectory by 0.5 deg of pitch about its newest
  // keyframe (loops at its end, its far start swinging), and moves that keyframe up by 5 cm.
  const Eigen::Isometry3d newest = s.keyframes[1][49].T_world_truth;
  Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
  turn.linear() = geometry::from_rpy(0, 0.5 * M_PI / 180, 0);
  turn.translation().z() = 0.05;
  const Eigen::Isometry3d offset = newest * turn * newest.inverse();
  const CentralResult moved = central_for(s, 1, 49, offset);
  const Eigen::Isometry3d want = moved.T_world_robot.inverse() * moved.poses.back().second;  // newest, odometry frame
  core.on_central_result(moved);
  int steps = 0;
  for (; steps < 100; ++steps) {
    const auto out = core.step(t += 50ms, true);
    ASSERT_TRUE(out.correction);
    ASSERT_EQ(out.correction->poses.back().first, 49u);
    const Eigen::Isometry3d got = out.correction->T_world_robot.inverse() * out.correction->poses.back().second;
    EXPECT_LT((got.translation() - want.translation()).norm(), 1e-6) << "step " << steps;
    EXPECT_LT(geometry::rotation_angle(got.rotation().transpose() * want.rotation()), 1e-8) << "step " << steps;
    if ((out.correction->T_world_robot.matrix() - moved.T_world_robot.matrix()).norm() < 1e-9) break;
  }
  EXPECT_GT(steps, 1) << "the world transform should have taken the change in more than one step";
  EXPECT_LT(steps, 100);
}

// A new solution that changes only the robot's first keyframes (a loop at its start turning them by
// 0.5 deg of pitch) leaves the corrected newest keyframe where it was: T_world_robot is fitted to the
// whole trajectory, not held at the first keyframe, which would swing the far end by metres.
TEST(PeerCore, AChangeAtTheStartOfTheTrajectoryDoesNotSwingItsEnd) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  Nanos t = join_central(core, s, 1, 50, 1s);
  auto newest_in_odometry = [](const Correction& c) { return c.T_world_robot.inverse() * c.poses.back().second; };
  const Eigen::Isometry3d before = newest_in_odometry(*core.step(t += 50ms, true).correction);
  CentralResult bent = central_for(s, 1, 49, Eigen::Isometry3d::Identity());
  Eigen::Isometry3d pitch = Eigen::Isometry3d::Identity();
  pitch.linear() = geometry::from_rpy(0, 0.5 * M_PI / 180, 0);
  for (size_t i = 0; i < 3; ++i) bent.poses[i].second = bent.poses[i].second * pitch;
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> odom_world;
  for (const auto& [id, T] : bent.poses) odom_world.emplace_back(s.keyframes[1][id].T_odom_keyframe, T);
  bent.T_world_robot = geometry::align_poses(odom_world).T_dst_src;
  const double span =
      (s.keyframes[1][49].T_world_truth.translation() - s.keyframes[1][0].T_world_truth.translation()).norm();
  ASSERT_GT(span * 0.5 * M_PI / 180, 0.3) << "held at the first keyframe, the end would swing by this much";
  core.on_central_result(bent);
  for (int step = 0; step < 50; ++step) {
    const auto out = core.step(t += 50ms, true);
    ASSERT_TRUE(out.correction);
    const Eigen::Isometry3d now = newest_in_odometry(*out.correction);
    EXPECT_LT((now.translation() - before.translation()).norm(), 0.01) << "step " << step;
    EXPECT_LT(geometry::rotation_angle(before.rotation().transpose() * now.rotation()), 1e-3) << "step " << step;
  }
}

TEST(PeerCore, LivelinessLossSwitchesToDistributedAndKeepsCorrectingFromTheCentralEstimate) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  Nanos t = join_central(core, s, 1, 60, 1500ms);
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  const auto out = core.step(t += 50ms, false);
  ASSERT_TRUE(out.transition);
  EXPECT_EQ(out.transition->reason, SwitchReason::kLivelinessLost);
  EXPECT_EQ(core.mode(), Mode::kDistributed);
  // New keyframes keep coming; the distributed back-end keeps correcting without a jump.
  for (uint32_t id = 60; id < 80; ++id) {
    core.add_keyframe(kf_from(s.keyframes[1][id]), t);
    const auto o = core.step(t += 100ms, false);
    ASSERT_TRUE(o.correction);
    EXPECT_FALSE(o.correction->from_central);
  }
  EXPECT_GT(core.distributed_rounds(), 10u);
  // Anchored on the central's last estimate: the pose at the switch stays where it was.
  const Eigen::Isometry3d T_world_59 = s.keyframes[1][59].T_world_truth;
  const std::vector<std::pair<uint32_t, Eigen::Isometry3d>> est = core.step(t += 100ms, false).correction->poses;
  const auto it = std::find_if(est.begin(), est.end(), [](const auto& p) { return p.first == 59; });
  ASSERT_NE(it, est.end());
  EXPECT_LT((it->second.translation() - T_world_59.translation()).norm(), 0.05);
}

// Back from DISTRIBUTED, the central's results are relayed only once the central holds every
// keyframe made before the rejoin: its last result from before the cut, or one from a graph still
// taking in the re-sent backlog, would pull the front-end back to where the robot was then. A
// placement from the robot's own hint (the central has not put it in its graph yet) holds every
// keyframe but no correction: it is not relayed either, nor lets the partial backlog after it
// through; the distributed estimate stays the one source.
TEST(PeerCore, AfterARejoinTheCentralIsRelayedOnlyOnceItHoldsTheNewKeyframes) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  const auto rejoined = cut_and_rejoin(core, s);
  ASSERT_TRUE(rejoined);
  Nanos t = *rejoined;
  // Back in reach: the central's results hold keyframes up to 59, then all of them placed by the
  // robot's hint, then a partial backlog (up to 70), 1 m higher than the truth; none is relayed.
  Eigen::Isometry3d up = Eigen::Isometry3d::Identity();
  up.translation().z() = 1.0;
  const Eigen::Isometry3d before = core.step(t += 50ms, true).correction->T_world_robot;
  for (int i = 0; i < 40; ++i) {
    if (i == 0) core.on_central_result(central_for(s, 1, 59, up));
    if (i == 10) {
      CentralResult hint = central_for(s, 1, 79, up);
      hint.from_hint = true;
      core.on_central_result(hint);
    }
    if (i == 20) core.on_central_result(central_for(s, 1, 70, up));
    const auto out = core.step(t += 50ms, true);
    ASSERT_TRUE(out.correction);
    EXPECT_FALSE(out.correction->from_central) << "step " << i;
    EXPECT_EQ(out.correction->poses.back().first, 79u) << "step " << i << ": not the distributed estimate";
    EXPECT_LT(std::abs(out.correction->T_world_robot.translation().z() - before.translation().z()), 0.05)
        << "step " << i;
  }
  // Once a result holds keyframe 79, it is relayed (and followed in bounded steps).
  core.on_central_result(central_for(s, 1, 79, up));
  const auto out = core.step(t += 50ms, true);
  ASSERT_TRUE(out.correction);
  EXPECT_TRUE(out.correction->from_central);
  EXPECT_EQ(out.correction->poses.size(), 80u);
  EXPECT_GT(out.correction->T_world_robot.translation().z() - before.translation().z(), 0.05);
}

// A central result that holds fewer of the robot's keyframes than one already relayed (the central
// placing the robot anew, with a gap in the re-sent backlog) is not relayed until it catches up.
TEST(PeerCore, ACentralResultThatFallsBehindOneRelayedIsNotRelayed) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  Nanos t = join_central(core, s, 1, 50, 1s);
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  for (uint32_t id = 50; id < 80; ++id) core.add_keyframe(kf_from(s.keyframes[1][id]), t);
  core.on_central_result(central_for(s, 1, 79, Eigen::Isometry3d::Identity()));
  auto out = core.step(t += 50ms, true);
  ASSERT_TRUE(out.correction);
  ASSERT_TRUE(out.correction->from_central);
  for (int i = 0; i < 200; ++i) {  // until the world transform has reached the central's
    const Eigen::Isometry3d prev = out.correction->T_world_robot;
    out = core.step(t += 50ms, true);
    if ((out.correction->T_world_robot.matrix() - prev.matrix()).norm() < 1e-12) break;
  }
  const Eigen::Isometry3d before = out.correction->T_world_robot;
  Eigen::Isometry3d up = Eigen::Isometry3d::Identity();
  up.translation().z() = 1.0;
  core.on_central_result(central_for(s, 1, 60, up));  // falls behind keyframe 79
  for (int i = 0; i < 20; ++i) {
    out = core.step(t += 50ms, true);
    ASSERT_TRUE(out.correction);
    EXPECT_FALSE(out.correction->from_central) << "step " << i;
    EXPECT_LT((out.correction->T_world_robot.translation() - before.translation()).norm(), 1e-9) << "step " << i;
  }
  core.on_central_result(central_for(s, 1, 79, up));  // caught up: relayed, and followed in bounded steps
  out = core.step(t += 50ms, true);
  ASSERT_TRUE(out.correction);
  EXPECT_TRUE(out.correction->from_central);
  EXPECT_GT(out.correction->T_world_robot.translation().z() - before.translation().z(), 0.05);
}

TEST(PeerCore, ResendsWhatTheCentralHasNotAcknowledged) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(2));
  for (uint32_t id = 0; id < 10; ++id) {
    core.add_keyframe(kf_from(s.keyframes[2][id]), 0s);
  }
  LoopRecord own{.sender = 2, .sender_incarnation = 3, .robot_a = 0, .robot_b = 2, .keyframe_b = 3};
  for (uint32_t seq = 0; seq < 4; ++seq) {
    own.seq = seq;
    own.keyframe_a = seq;
    core.add_loop(own, 0s);
  }
  CentralResult r = central_for(s, 2, 4, Eigen::Isometry3d::Identity());
  core.on_central_result(r);
  core.on_ack(AckIn{11, 3, 4, 1});
  Nanos t = 0s;
  std::vector<uint32_t> kfs, loops;
  for (; t <= 3s; t += 100ms) {
    const auto out = core.step(t, true);
    kfs.insert(kfs.end(), out.resend_keyframes.begin(), out.resend_keyframes.end());
    loops.insert(loops.end(), out.resend_loops.begin(), out.resend_loops.end());
    if (!kfs.empty()) {
      break;
    }
  }
  EXPECT_EQ(kfs, (std::vector<uint32_t>{5, 6, 7, 8, 9}));
  EXPECT_EQ(loops, (std::vector<uint32_t>{2, 3}));
  // An acknowledgement about another incarnation of this robot changes nothing.
  core.on_ack(AckIn{11, 99, 9, 3});
  // A restarted central (new incarnation) knows nothing: on the next rejoin everything goes again.
  CentralResult fresh = r;
  fresh.central_incarnation = 12;
  core.on_central_result(fresh);
  core.step(t += 100ms, false);  // lost
  std::vector<uint32_t> again;
  for (t += 100ms; t <= 10s; t += 100ms) {
    const auto out = core.step(t, true);
    if (out.transition) {
      again = out.resend_keyframes;
      EXPECT_TRUE(out.world_transform.has_value());
      break;
    }
  }
  EXPECT_EQ(again.size(), 10u);
}

// A long backlog goes out in chunks of max_resend_per_step, one per resend period, each keyframe
// once until its grace has passed without an acknowledgement.
TEST(PeerCore, ALongBacklogIsResentInChunksEachKeyframeOnce) {
  const auto s = test::make_swarm_stream({});
  PeerConfig c = config(2);
  c.max_resend_per_step = 50;
  PeerCore core(c);
  for (uint32_t id = 0; id < 120; ++id) {
    core.add_keyframe(kf_from(s.keyframes[2][id]), 0s);
  }
  std::map<uint32_t, int> sent;
  std::vector<size_t> chunks;
  Nanos t = 0s;
  for (; t < 1900ms; t += 50ms) {  // joins after the 1 s dwell; nothing is acknowledged
    const auto out = core.step(t, true);
    if (!out.resend_keyframes.empty()) chunks.push_back(out.resend_keyframes.size());
    for (uint32_t id : out.resend_keyframes) ++sent[id];
  }
  EXPECT_EQ(chunks, (std::vector<size_t>{50, 50, 20})) << "one chunk per resend period";
  EXPECT_EQ(sent.size(), 120u);
  for (const auto& [id, n] : sent) EXPECT_EQ(n, 1) << "keyframe " << id << " re-sent before its grace passed";
  // Still unacknowledged a grace later: sent again.
  size_t again = 0;
  for (; t <= 2900ms; t += 50ms) again += core.step(t, true).resend_keyframes.size();
  EXPECT_EQ(again, 120u);
}

// Own keyframes go on to the central only while CENTRALIZED; on the switch to DISTRIBUTED those
// forwarded but not yet delivered are to be dropped (they come with the backlog on rejoining).
TEST(PeerCore, ForwardsKeyframesOnlyWhileCentralizedAndDropsUndeliveredOnesOnLeaving) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  EXPECT_FALSE(core.forwards_keyframes()) << "a robot starts DISTRIBUTED";
  for (uint32_t id = 0; id < 10; ++id) core.add_keyframe(kf_from(s.keyframes[1][id]), 0s);
  core.on_central_result(central_for(s, 1, 9, Eigen::Isometry3d::Identity()));
  Nanos t = 0s;
  for (; core.mode() != Mode::kCentralized && t <= 2s; t += 50ms) {
    EXPECT_FALSE(core.step(t, true).drop_undelivered_keyframes) << "no switch to DISTRIBUTED";
  }
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  EXPECT_TRUE(core.forwards_keyframes());
  const StepOutput cut = core.step(t += 50ms, false);
  ASSERT_TRUE(cut.transition);
  EXPECT_TRUE(cut.drop_undelivered_keyframes);
  EXPECT_FALSE(core.forwards_keyframes());
  EXPECT_FALSE(core.step(t += 50ms, false).drop_undelivered_keyframes) << "only at the switch";
}

// Robot 1 with a central range of 50 m (hysteresis 5 m).
PeerConfig range_config() {
  PeerConfig c = config(1);
  c.rtdos.range_m = 50;
  c.rtdos.hysteresis_m = 5;
  return c;
}

TEST(PeerCore, RangeTriggerUsesTheEstimatedDistanceToTheCentral) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(range_config());
  core.add_keyframe(kf_from(s.keyframes[1][0]), 0s);
  core.on_central_result(central_for(s, 1, 0, Eigen::Isometry3d::Identity()));
  const Eigen::Vector3d p = s.keyframes[1][0].T_world_truth.translation();
  core.on_central_position(p + Eigen::Vector3d(30, 0, 0));
  Nanos t = 0s;
  for (; t <= 1500ms; t += 100ms) {
    core.step(t, true);
  }
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  ASSERT_NEAR(*core.distance_to_central(), 30.0, 1e-6);
  core.on_central_position(p + Eigen::Vector3d(60, 0, 0));
  const auto out = core.step(t += 100ms, true);
  ASSERT_TRUE(out.transition);
  EXPECT_EQ(out.transition->reason, SwitchReason::kOutOfRange);
  EXPECT_NEAR(*out.transition->distance_m, 60.0, 1e-6);
}

// A restarted central knows no world until its host robot's poses reach it: its position is unknown
// then, and so is the distance to it, which keeps a robot CENTRALIZED (not "out of range" of the origin).
TEST(PeerCore, ACentralWithoutAWorldIsAtAnUnknownDistance) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(range_config());
  core.add_keyframe(kf_from(s.keyframes[1][0]), 0s);
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(100, 0, 0);  // the robot 100 m from the world origin
  core.on_central_result(central_for(s, 1, 0, far));
  Nanos t = 0s;
  for (; t <= 1500ms; t += 100ms) {
    core.step(t, true);
  }
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  ASSERT_TRUE(core.world_pose());
  const Eigen::Vector3d p = core.world_pose()->translation();
  ASSERT_GT(p.norm(), 60.0) << "the robot is out of range of the origin";
  core.on_central_position(p + Eigen::Vector3d(10, 0, 0));
  EXPECT_FALSE(core.step(t += 100ms, true).transition);
  ASSERT_NEAR(*core.distance_to_central(), 10.0, 1e-6);
  core.on_central_position(std::nullopt);  // the central restarted
  EXPECT_FALSE(core.distance_to_central());
  for (int i = 0; i < 10; ++i) {
    EXPECT_FALSE(core.step(t += 100ms, true).transition);
  }
  EXPECT_EQ(core.mode(), Mode::kCentralized);
}

TEST(PeerCore, TwoPeersPlaceEachOtherThroughSeparatorsAlone) {
  // No central at all: robot 0 (lowest id) anchors the group in its odometry frame; robot 1 starts
  // in its own odometry frame (about 120 m and a quarter turn away) and is placed only through the
  // separator poses robot 0 sends for their inter-robot loops. The rounds then keep lowering the
  // joint cost toward the centralized optimum (slowly, as block Gauss-Seidel does on strongly
  // coupled robots; see common/graph's README).
  test::SwarmStreamOptions o;
  o.robots = 2;
  o.keyframes_per_robot = 150;
  const auto s = test::make_swarm_stream(o);
  PeerCore r0(config(0)), r1(config(1));
  for (uint32_t id = 0; id < 150; ++id) {
    r0.add_keyframe(kf_from(s.keyframes[0][id]), 0s);
    r1.add_keyframe(kf_from(s.keyframes[1][id]), 0s);
  }
  graph::PoseGraph central;  // the same two-robot graph, solved jointly
  for (uint32_t r = 0; r < 2; ++r) {
    for (const auto& kf : s.keyframes[r]) {
      if (kf.id > 0) {
        central.add_between(graph::make_key(r, kf.id - 1u), graph::make_key(r, kf.id), kf.T_prev_keyframe,
                            kf.information);
      }
    }
  }
  size_t inter = 0;
  for (const auto& l : s.loops) {
    const LoopRecord lr = loop_from(l);
    if (l.robot_a == 0 || l.robot_b == 0) r0.add_loop(lr, 0s);
    if (l.robot_a == 1 || l.robot_b == 1) r1.add_loop(lr, 0s);
    inter += l.robot_a != l.robot_b ? 1 : 0;
    central.add_between(graph::make_key(l.robot_a, l.keyframe_a), graph::make_key(l.robot_b, l.keyframe_b), l.T_a_b,
                        l.information);
  }
  ASSERT_GT(inter, 5u);
  central.add_prior(graph::make_key(0, 0), Eigen::Isometry3d::Identity(), Matrix6d::Identity() * 1e6);
  ASSERT_TRUE(graph::chordal_initialise(central));
  graph::solve(central, graph::SolverOptions{});  // no robust loss: the distributed rounds use none

  Nanos t = 0s;
  auto run_rounds = [&](int n) {
    for (int i = 0; i < n; ++i) {
      t += 100ms;
      const auto o0 = r0.step(t, false);
      const auto o1 = r1.step(t, false);
      for (const auto& sep : o0.separators) {
        if (sep.target == 1) r1.on_separator(0, sep);
      }
      for (const auto& sep : o1.separators) {
        if (sep.target == 0) r0.on_separator(1, sep);
      }
    }
    graph::PoseGraph joint = central;
    const StepOutput s0 = r0.step(t, false);
    const StepOutput s1 = r1.step(t, false);
    for (const auto& [id, T] : s0.correction->poses) joint.poses[graph::make_key(0, id)] = T;
    for (const auto& [id, T] : s1.correction->poses) joint.poses[graph::make_key(1, id)] = T;
    return joint;
  };
  const graph::PoseGraph after10 = run_rounds(10);
  const graph::PoseGraph after40 = run_rounds(30);
  const double f_central = graph::full_information_cost(central);
  const double f10 = graph::full_information_cost(after10);
  const double f40 = graph::full_information_cost(after40);
  double worst = 0;
  for (uint32_t id = 0; id < 150; ++id) {
    const Key k = graph::make_key(1, id);
    worst = std::max(worst, (after40.poses.at(k).translation() - central.poses.at(k).translation()).norm());
  }
  std::printf("joint cost: after 10 rounds %.1f, after 40 %.1f, centralized %.1f; robot 1 worst %.2f m from it\n", f10,
              f40, f_central, worst);
  EXPECT_LT(worst, 5.0) << "robot 1 is not placed in robot 0's frame";
  // What robot 1 knows, as a graph: its own keyframes and odometry, and the loops touching it whose
  // other end it has (robot 0's separator poses).
  const graph::PoseGraph known = r1.graph();
  size_t own = 0, separators = 0, loops_touching = 0;
  for (const auto& [k, T] : known.poses) (graph::robot_of(k) == 1 ? own : separators) += 1;
  for (const auto& l : s.loops) loops_touching += (l.robot_a == 1 || l.robot_b == 1) ? 1 : 0;
  EXPECT_EQ(own, 150u);
  EXPECT_GT(separators, 0u);
  EXPECT_EQ(known.count(graph::FactorKind::kOdometry), 149u);
  EXPECT_EQ(known.count(graph::FactorKind::kLoop), loops_touching);
  EXPECT_LT(f40, f10) << "the rounds stopped improving the joint cost";
  EXPECT_GE(f40, f_central * (1 - 1e-9));
}

TEST(PeerCore, SeparatorPosesGoAgainOnlyOnceTheyMovedOrOnRefresh) {
  // A settled pose is not sent again until the refresh; a moved one is. Block solves alone, so that
  // robot 1's pose pulls keyframe 5 (a coarse step would move robot 1 onto the loop instead).
  const auto s = three_robot_stream();
  PeerConfig c0 = config(0);
  c0.separator_refresh = 2s;
  c0.coarse_step = false;
  PeerCore r0(c0);
  add_robot0_with_a_loop_to_robot1(s, r0);
  size_t sent = 0;
  Nanos t = 0s;
  for (int i = 0; i < 20; ++i) {  // 0.1-2.0 s: the first send, then the estimate settles (robot 0 is alone)
    for (const auto& sep : r0.step(t += 100ms, false).separators) {
      ASSERT_EQ(sep.target, 1u);
      sent += sep.poses.size();
    }
  }
  EXPECT_EQ(sent, 1u) << "an unmoved separator pose was sent again before the refresh";
  const auto refresh = r0.step(t += 100ms, false);  // 2.1 s: 2 s after the first send
  ASSERT_EQ(refresh.separators.size(), 1u);
  EXPECT_EQ(refresh.separators[0].poses.size(), 1u);
  EXPECT_EQ(refresh.separators[0].poses[0].first, 5u);

  // Robot 1's pose arrives: the loop now pulls keyframe 5, which moves and goes out before the next refresh.
  r0.on_separator(1, {{7u, refresh.separators[0].poses[0].second * Eigen::Translation3d(0.3, 0.0, 0.0)}});
  size_t moved_sends = 0;
  for (int i = 0; i < 5; ++i) {
    for (const auto& sep : r0.step(t += 100ms, false).separators) moved_sends += sep.poses.size();
  }
  EXPECT_GE(moved_sends, 1u) << "a moved separator pose was held back";
}

TEST(PeerCore, APeerMatchedAnewGetsEverySeparatorPoseAtTheNextRound) {
  const auto s = three_robot_stream();
  PeerCore r0(config(0));  // refresh 30 s: only the first send and the resends below within the test
  add_robot0_with_a_loop_to_robot1(s, r0);
  LoopRecord l = loop_from(s.loops.front());  // and one from its keyframe 8 to robot 2's 3
  l.seq += 1;
  l.robot_a = 0;
  l.keyframe_a = 8;
  l.robot_b = 2;
  l.keyframe_b = 3;
  r0.add_loop(l, 0s);
  Nanos t = 0s;
  std::map<uint32_t, std::vector<uint32_t>> sent;  // target -> keyframe ids, in order
  const auto rounds = [&](int n) {
    sent.clear();
    for (int i = 0; i < n; ++i) {
      for (const auto& sep : r0.step(t += 100ms, false).separators) {
        for (const auto& [id, T] : sep.poses) sent[sep.target].push_back(id);
      }
    }
  };
  // With the coarse step every robot of the group gets every own keyframe an inter-robot loop touches.
  const std::vector<uint32_t> both{5, 8};
  rounds(20);  // the first send to each peer, then the estimate settles (robot 0 is alone)
  EXPECT_EQ(sent[1], both);
  EXPECT_EQ(sent[2], both);
  rounds(20);
  EXPECT_TRUE(sent.empty()) << "settled separator poses were sent again";

  r0.resend_separators_to(2);  // robot 2's reader matched anew
  rounds(1);
  EXPECT_EQ(sent[2], both) << "the peer matched anew did not get its separator poses";
  EXPECT_EQ(sent.count(1), 0u) << "a peer that missed nothing got its separator pose again";
  rounds(20);
  EXPECT_TRUE(sent.empty()) << "the resend repeated";
}

TEST(PeerCore, TellsItsPeersWhetherItsRoundsRunTheCoarseStep) {
  const auto s = three_robot_stream();
  PeerCore r0(config(0));
  add_robot0_with_a_loop_to_robot1(s, r0);
  Nanos t = 0s;
  StepOutput out = r0.step(t += 100ms, false);  // DISTRIBUTED at once, without the central's estimate
  ASSERT_EQ(out.separators.size(), 1u);
  EXPECT_TRUE(out.separators[0].coarse_step);
  EXPECT_EQ(out.separators[0].inter_robot_loops, 1u);
  for (int i = 0; i < 20; ++i) r0.step(t += 100ms, false);
  r0.on_central_result(central_for(s, 0, 9, Eigen::Isometry3d::Identity()));
  out = r0.step(t += 100ms, false);
  ASSERT_EQ(out.separators.size(), 1u) << "the change did not go out at once";
  EXPECT_FALSE(out.separators[0].coarse_step) << "the central's estimate anchors its rounds";
  EXPECT_EQ(r0.separator_traffic().loops, 0u) << "robot 0 has no loop to relay to robot 1";
}

TEST(PeerCore, ACentralizedPeerGetsNoSeparatorPosesUntilItReportsDistributed) {
  const auto s = three_robot_stream();
  PeerCore r0(config(0));  // refresh 30 s
  add_robot0_with_a_loop_to_robot1(s, r0);
  Nanos t = 0s;
  std::vector<uint32_t> sent;  // keyframe ids sent to robot 1
  const auto rounds = [&](int n) {
    sent.clear();
    for (int i = 0; i < n; ++i) {
      for (const auto& sep : r0.step(t += 100ms, false).separators) {
        ASSERT_EQ(sep.target, 1u);
        for (const auto& [id, T] : sep.poses) sent.push_back(id);
      }
    }
  };
  r0.on_peer_mode(1, Mode::kCentralized);
  rounds(20);
  EXPECT_TRUE(sent.empty()) << "a CENTRALIZED peer got separator poses";
  r0.on_peer_mode(1, Mode::kDistributed);
  rounds(1);
  EXPECT_EQ(sent, std::vector<uint32_t>{5}) << "the peer gone DISTRIBUTED did not get its separator pose at once";
  rounds(20);
  EXPECT_TRUE(sent.empty()) << "settled separator poses were sent again";
  // Back to CENTRALIZED and DISTRIBUTED again: it may have missed moves meanwhile, so all of them again.
  r0.on_peer_mode(1, Mode::kCentralized);
  rounds(5);
  EXPECT_TRUE(sent.empty());
  r0.on_peer_mode(1, Mode::kDistributed);
  rounds(1);
  EXPECT_EQ(sent, std::vector<uint32_t>{5});
}

}  // namespace
}  // namespace cdc::peer

namespace cdc::peer {
namespace {

using namespace std::chrono_literals;

// The core's world trajectory holds n poses, their stamps increasing.
void expect_trajectory_in_stamp_order(const PeerCore& core, size_t n) {
  const geometry::Trajectory t = core.world_trajectory();
  ASSERT_EQ(t.size(), n);
  for (size_t i = 1; i < t.size(); ++i) EXPECT_GT(t[i].stamp_ns, t[i - 1].stamp_ns);
}

// Robot 1's first front-end makes keyframes 0..99 of incarnation 3; a restarted one continues the
// sequence with 100..199 (incarnation 3, after a weak link): the core holds all 200, chained.
TEST(PeerCore, ARestartedFrontEndThatContinuesTheSequenceHasEveryKeyframeHeld) {
  test::SwarmStreamOptions so;
  so.keyframes_per_robot = 200;
  const auto s = test::make_swarm_stream(so);
  PeerCore core(config(1));
  for (uint32_t id = 0; id < 200; ++id) {
    OwnKeyframe k = kf_from(s.keyframes[1][id]);
    if (id == 100) k.information = Matrix6d::Identity() * 1e-2;  // the link across the restart
    EXPECT_EQ(core.add_keyframe(k, 0s).outcome, Admission::kAccepted) << "keyframe " << id;
  }
  EXPECT_EQ(core.keyframes_held(), 200u);
  EXPECT_EQ(core.last_keyframe_id(), 199);
  EXPECT_EQ(core.graph().count(graph::FactorKind::kOdometry), 199u);
  expect_trajectory_in_stamp_order(core, 200u);
}

// The hole of a front-end that numbers afresh: keyframes whose ids the core holds, of another
// incarnation or another stamp, are refused with the robot, the id and both incarnations named; the
// core's copy stays (it is what is re-sent and written out). A re-delivery of a held keyframe is a
// duplicate, and a keyframe of another incarnation beyond the held ids is refused too.
TEST(PeerCore, AKeyframeConflictingWithTheSequenceIsRefusedAndNamed) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  for (uint32_t id = 0; id < 100; ++id) core.add_keyframe(kf_from(s.keyframes[1][id]), 0s);
  EXPECT_EQ(core.add_keyframe(kf_from(s.keyframes[1][7]), 1s).outcome, Admission::kDuplicate);
  for (uint32_t id = 0; id < 100; ++id) {
    OwnKeyframe afresh = kf_from(s.keyframes[1][id], 4);
    afresh.stamp_ns += 500'000'000'000;  // later data, numbered from 0 again
    const KeyframeAdmission a = core.add_keyframe(afresh, 1s);
    ASSERT_EQ(a.outcome, Admission::kRefused);
    if (id == 5) {
      EXPECT_NE(a.reason.find("robot 1 keyframe 5 of incarnation 4"), std::string::npos) << a.reason;
      EXPECT_NE(a.reason.find("held already from incarnation 3"), std::string::npos) << a.reason;
      EXPECT_NE(a.reason.find("continues after keyframe 99 of incarnation 3"), std::string::npos) << a.reason;
    }
  }
  OwnKeyframe same_incarnation = kf_from(s.keyframes[1][3]);
  same_incarnation.stamp_ns += 1;
  EXPECT_EQ(core.add_keyframe(same_incarnation, 1s).outcome, Admission::kRefused);
  const KeyframeAdmission beyond = core.add_keyframe(kf_from(s.keyframes[1][100], 4), 1s);
  EXPECT_EQ(beyond.outcome, Admission::kRefused);
  EXPECT_NE(beyond.reason.find("not of the keyframe sequence held (incarnation 3)"), std::string::npos)
      << beyond.reason;
  EXPECT_EQ(core.keyframe_counters().refused, 102u);
  EXPECT_EQ(core.keyframe_counters().duplicate, 1u);
  EXPECT_EQ(core.keyframes_held(), 100u);
  ASSERT_NE(core.keyframe(5), nullptr);
  EXPECT_EQ(core.keyframe(5)->incarnation, 3u);
  EXPECT_EQ(core.keyframe(5)->stamp_ns, stamp_of(5));
  expect_trajectory_in_stamp_order(core, 100u);
}

// The trajectory written at shutdown follows the corrections the core published.
TEST(PeerCore, WorldTrajectoryFollowsThePublishedCorrections) {
  const auto s = test::make_swarm_stream({});
  PeerCore core(config(1));
  EXPECT_TRUE(core.world_trajectory().empty());
  const Nanos t = join_central(core, s, 1, 20, 1500ms);
  ASSERT_EQ(core.mode(), Mode::kCentralized);
  Eigen::Isometry3d up = Eigen::Isometry3d::Identity();
  up.translation().z() = 0.5;
  core.on_central_result(central_for(s, 1, 19, up));
  std::optional<Correction> last;
  for (Nanos now = t; now < t + 20s; now += 50ms) {
    if (auto out = core.step(now, true); out.correction) last = out.correction;
  }
  ASSERT_TRUE(last);
  const geometry::Trajectory traj = core.world_trajectory();
  ASSERT_EQ(traj.size(), 20u);
  EXPECT_EQ(traj[19].stamp_ns, stamp_of(19));
  const auto& [id, T] = last->poses.back();
  EXPECT_TRUE(traj[id].pose.isApprox(T, 1e-9));
  EXPECT_NEAR(traj[19].pose.translation().z() - s.keyframes[1][19].T_world_truth.translation().z(), 0.5, 1e-6);
}

}  // namespace
}  // namespace cdc::peer
