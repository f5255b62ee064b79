// The loop-closure core end to end on simulated scans: two robots drive the same block; every loop it
// publishes is true (1 m / 5 deg), and it finds the robots' shared places.
#include "cdc/loop_closure/loop_core.hpp"
#include "circle_lap.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/missions.hpp"
#include "cdc/sim/world.hpp"

#include <gtest/gtest.h>

#include <algorithm>

#include <map>
#include <random>
#include <set>

namespace cdc::loops {
namespace {

using test::circle_lap;

TEST(LoopCore, FindsTrueLoopsBetweenTwoRobotsOnTheSameBlock) {
  // Robots 0 and 1 drive the same circle (40 m radius), robot 1 a little behind; keyframes every 2 m.
  const auto [lap, world] = circle_lap(40, 70);  // 140 m
  const sim::LidarModel lidar = sim::LidarModel::vlp16();
  std::mt19937_64 rng(1);

  LoopParams params;
  LoopCore core(params);
  LoopParams unlevelled = params;  // the same loops with the registration's information as it is
  unlevelled.tilt_information_scale = 1.0;
  LoopCore raw_core(unlevelled);
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::vector<LoopOut> published;
  std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>, graph::Matrix6d> raw_information;
  const size_t step = 10;  // 2 m at 2 m/s and 10 Hz
  for (size_t k = 0; k * step + 40 < lap.size(); ++k) {
    for (uint32_t r = 0; r < 2; ++r) {
      const size_t i = k * step + (r == 1 ? 40 : 0);  // robot 1 is 8 m further along the same path
      const Eigen::Isometry3d T = lap[i].pose;
      KeyframeIn kf;
      kf.robot = r;
      kf.id = static_cast<uint32_t>(k);
      if (k > 0) kf.T_prev = truth[{r, static_cast<uint32_t>(k - 1)}].inverse() * T;
      kf.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
      kf.T_odom = T;  // a levelled odometry's tilt
      for (const auto& p : sim::sweep(world, lidar, [&](double) { return T; }, rng)) kf.cloud.emplace_back(p.x, p.y, p.z);
      truth[{r, kf.id}] = T;
      for (const auto& l : raw_core.add_keyframe(kf)) {
        raw_information[{l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b}] = l.information;
      }
      for (const auto& l : core.add_keyframe(std::move(kf))) published.push_back(l);
    }
  }
  size_t inter = 0;
  double chi2_t = 0;
  for (const auto& l : published) {
    ASSERT_FALSE(l.withdrawn);
    const Eigen::Isometry3d gt = truth.at({l.robot_a, l.keyframe_a}).inverse() * truth.at({l.robot_b, l.keyframe_b});
    const Eigen::Isometry3d e = gt.inverse() * l.T_a_b;
    EXPECT_LT(e.translation().norm(), 1.0) << l.robot_a << "/" << l.keyframe_a << " - " << l.robot_b << "/" << l.keyframe_b;
    EXPECT_LT(Eigen::AngleAxisd(e.rotation()).angle(), 5 * M_PI / 180);
    // The registration's information, levelled: about the query keyframe's horizontal axes the
    // rotation information is scaled by tilt_information_scale, about its vertical axis it is kept.
    const auto raw = raw_information.find({l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b});
    ASSERT_NE(raw, raw_information.end()) << "the same loop without levelling";
    const Eigen::Vector3d up = truth.at({l.robot_b, l.keyframe_b}).linear().transpose() * Eigen::Vector3d::UnitZ();
    const Eigen::Vector3d side = up.cross(Eigen::Vector3d::UnitX()).normalized(), ahead = side.cross(up);
    const Eigen::Matrix3d info_r = l.information.bottomRightCorner<3, 3>(), raw_r = raw->second.bottomRightCorner<3, 3>();
    EXPECT_NEAR(up.dot(info_r * up), up.dot(raw_r * up), 1e-6 * up.dot(raw_r * up));
    EXPECT_NEAR(side.dot(info_r * side), params.tilt_information_scale * side.dot(raw_r * side), 1e-6 * side.dot(raw_r * side));
    EXPECT_NEAR(ahead.dot(info_r * ahead), params.tilt_information_scale * ahead.dot(raw_r * ahead),
                1e-6 * ahead.dot(raw_r * ahead));
    EXPECT_TRUE((l.information.topLeftCorner<3, 3>().isApprox(raw->second.topLeftCorner<3, 3>(), 1e-9))) << "translation untouched";
    // The registration's translation information (the loop's / loop_information_scale) matches its error.
    const Eigen::Vector3d dt = l.T_a_b.translation() - gt.translation();
    chi2_t += dt.dot(l.information.topLeftCorner<3, 3>() * dt) / params.loop_information_scale;
    inter += l.robot_a != l.robot_b ? 1 : 0;
  }
  const double mean_chi2_t = chi2_t / static_cast<double>(std::max<size_t>(published.size(), 1));
  std::printf("translation error against its information: mean chi2 %.2f (3 DoF)\n", mean_chi2_t);
  // Neither over- nor under-confident by more than 3x in variance (3 if exact).
  EXPECT_GT(mean_chi2_t, 1.0);
  EXPECT_LT(mean_chi2_t, 9.0);
  std::printf("%zu loops published (%zu inter-robot), %llu verified, %llu failed verification\n", published.size(), inter,
              static_cast<unsigned long long>(core.stats().verified),
              static_cast<unsigned long long>(core.stats().verification_failed));
  EXPECT_GE(inter, 10u);
}

// One robot drives 1.75 laps of a circle of 20 m radius. With its true odometry the second lap closes loops with the
// first; with odometry that has it climbing 0.5 m per keyframe (30 m up after a lap, beyond the
// gate of 15 m + 5 % of the 125 m driven), those candidates are never verified.
TEST(LoopCore, OwnCandidatesTheOdometryPutsFarAwayAreNotVerified) {
  const auto [lap, world] = circle_lap(20, 110);  // a 126 m lap
  const sim::LidarModel lidar = sim::LidarModel::vlp16();
  auto run = [&](double climb_m, double gate_m = 15) {
    std::mt19937_64 rng(1);
    LoopParams params;
    params.intra_gate_m = gate_m;
    LoopCore core(params);
    size_t intra = 0;
    Eigen::Isometry3d prev = Eigen::Isometry3d::Identity();
    for (size_t k = 0; k * 10 < lap.size(); ++k) {
      const Eigen::Isometry3d T = lap[k * 10].pose;
      KeyframeIn kf;
      kf.id = static_cast<uint32_t>(k);
      kf.T_prev = prev.inverse() * T;
      kf.T_prev.translation().z() += climb_m;
      prev = T;
      kf.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
      for (const auto& p : sim::sweep(world, lidar, [&](double) { return T; }, rng)) kf.cloud.emplace_back(p.x, p.y, p.z);
      for (const auto& l : core.add_keyframe(std::move(kf))) intra += l.robot_a == l.robot_b ? 1 : 0;
    }
    return std::make_pair(intra, core.stats());
  };
  const auto [true_loops, true_stats] = run(0.0);
  const auto [climb_loops, climb_stats] = run(0.5);
  std::printf("true odometry: %zu loops, %llu verified; climbing: %zu loops, %llu verified, %llu gated\n", true_loops,
              static_cast<unsigned long long>(true_stats.verified), climb_loops,
              static_cast<unsigned long long>(climb_stats.verified),
              static_cast<unsigned long long>(climb_stats.intra_gated));
  EXPECT_GE(true_loops, 5u);
  EXPECT_EQ(climb_loops, 0u);
  EXPECT_EQ(climb_stats.verified, 0u);
  EXPECT_GT(climb_stats.intra_gated, 0u);
}

// Three robots on one 40 m circle, 8 m apart; keyframes every 2 m with their true clouds.
struct Circle {
  sim::World world;
  geometry::Trajectory lap;
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::map<std::pair<uint32_t, uint32_t>, std::vector<Eigen::Vector3f>> clouds;
  Circle(double duration_s, uint32_t robots) {
    test::CircleLap l = circle_lap(40, duration_s);
    lap = std::move(l.lap);
    world = std::move(l.world);
    std::mt19937_64 rng(1);
    for (uint32_t r = 0; r < robots; ++r) {
      for (uint32_t k = 0; k * 10 + 40 * r < lap.size(); ++k) {
        const Eigen::Isometry3d T = lap[k * 10 + 40 * r].pose;
        truth[{r, k}] = T;
        auto& c = clouds[{r, k}];
        for (const auto& p : sim::sweep(world, sim::LidarModel::vlp16(), [&](double) { return T; }, rng)) c.emplace_back(p.x, p.y, p.z);
      }
    }
  }
  DescriptorIn descriptor(uint32_t r, uint32_t k, const LoopParams& p) const {
    return DescriptorIn{r, k, wire_form(lidar::make_scan_context(clouds.at({r, k}), p.scan_context)), truth.at({r, k})};
  }
  KeyframeIn keyframe(uint32_t r, uint32_t k) const {
    KeyframeIn kf;
    kf.robot = r;
    kf.id = k;
    if (k > 0) kf.T_prev = truth.at({r, k - 1}).inverse() * truth.at({r, k});
    kf.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
    kf.cloud = clouds.at({r, k});
    return kf;
  }
  // Robot 1's service at step k: robot 0's descriptor k (a reverse search), then robot 1's keyframe k
  // and its descriptor.
  LoopEvents feed_step(LoopCore& core, uint32_t k, const LoopParams& p, Nanos now) const {
    LoopEvents ev = core.add_descriptor(descriptor(0, k, p), now);
    ev.append(core.add_keyframe_data(keyframe(1, k), now));
    ev.append(core.add_descriptor(descriptor(1, k, p), now));
    return ev;
  }
  void expect_true(const LoopOut& l) const {
    const Eigen::Isometry3d e = (truth.at({l.robot_a, l.keyframe_a}).inverse() * truth.at({l.robot_b, l.keyframe_b})).inverse() * l.T_a_b;
    EXPECT_LT(e.translation().norm(), 1.0);
    EXPECT_LT(Eigen::AngleAxisd(e.rotation()).angle(), 5 * M_PI / 180);
  }
};

TEST(LoopCore, RequestsPeerCloudsAndVerifiesWhenTheyArrive) {
  // Robot 1's service: its own keyframes with clouds, robot 0's descriptors only (pose hints).
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;  // inter-robot loops only
  params.peer_request_spacing = 0;  // every candidate's cloud is asked for
  params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  std::vector<LoopOut> loops;
  std::set<std::pair<uint32_t, uint32_t>> asked;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(200);
    // A peer's descriptor is searched among this robot's own keyframes (a reverse search).
    LoopEvents ev = core.add_descriptor(c.descriptor(0, k, params), now);
    // The own descriptor may come before its keyframe: the search waits for the keyframe.
    LoopEvents own = core.add_descriptor(c.descriptor(1, k, params), now);
    EXPECT_TRUE(own.requests.empty() && own.loops.empty());
    ev.append(core.add_keyframe_data(c.keyframe(1, k), now));
    for (const auto& r : ev.requests) {
      EXPECT_EQ(r.robot, 0u);
      EXPECT_TRUE(asked.insert({r.robot, r.id}).second) << "asked twice for " << r.id;
      auto more = core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now);
      ev.append(std::move(more));
    }
    loops.insert(loops.end(), ev.loops.begin(), ev.loops.end());
  }
  EXPECT_GE(asked.size(), 5u);
  EXPECT_EQ(core.stats().replies, asked.size());
  EXPECT_EQ(core.pending_requests(), 0u);
  ASSERT_GE(loops.size(), 4u);
  for (const auto& l : loops) {
    EXPECT_FALSE(l.withdrawn);
    EXPECT_EQ(l.robot_a, 0u);
    EXPECT_EQ(l.robot_b, 1u);
    c.expect_true(l);
  }
  // A cloud nobody asked for is counted and ignored.
  core.on_cloud(0, 999, {}, now);
  EXPECT_EQ(core.stats().replies_unexpected, 1u);
}

// Loops that share a keyframe share its cloud: a registration that slid along a featureless stretch
// would slide the same way for each, and they would agree with each other. A consistent set is only
// published once it rests on two keyframes of each robot.
TEST(LoopCore, ASetOfLoopsThroughOneKeyframeIsNotPublished) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;
  params.peer_request_spacing = 0;
  params.max_verify = 4;  // several of robot 0's keyframes against each of robot 1's
  params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({0, k}) != 0; ++k) core.add_descriptor(c.descriptor(0, k, params), now);
  auto feed = [&](uint32_t k) {
    LoopEvents ev = core.add_keyframe_data(c.keyframe(1, k), now);
    ev.append(core.add_descriptor(c.descriptor(1, k, params), now));
    for (const auto& r : ev.requests) ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    return ev.loops;
  };
  EXPECT_TRUE(feed(5).empty()) << "loops through robot 1's keyframe 5 alone";
  const uint64_t consistent = core.stats().inter_proposed;
  ASSERT_GE(consistent, 2u) << "the single keyframe closed several (true) loops";
  std::vector<LoopOut> loops = feed(6);
  ASSERT_GE(loops.size(), 3u) << "a second keyframe: the set is published, the first keyframe's loops with it";
  std::set<uint32_t> own;
  for (const auto& l : loops) {
    own.insert(l.keyframe_b);
    c.expect_true(l);
  }
  EXPECT_EQ(own, (std::set<uint32_t>{5, 6}));
}

// A peer that was out of range comes back and its descriptors arrive all at once, after this robot
// has passed every one of those places: the reverse search still finds the loops.
TEST(LoopCore, DescriptorsOfAPeerBackInRangeAreSearchedAmongOwnKeyframes) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;  // inter-robot loops only
  params.peer_request_spacing = 0;
  params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    LoopEvents ev = core.add_keyframe_data(c.keyframe(1, k), now);
    ev.append(core.add_descriptor(c.descriptor(1, k, params), now));
    EXPECT_TRUE(ev.requests.empty() && ev.loops.empty()) << "nothing to find before the peer is heard";
  }
  std::vector<LoopOut> loops;
  size_t requests = 0;
  for (uint32_t k = 0; c.truth.count({0, k}) != 0; ++k) {
    now += std::chrono::milliseconds(10);
    LoopEvents ev = core.add_descriptor(c.descriptor(0, k, params), now);
    for (const auto& r : ev.requests) {
      EXPECT_EQ(r.robot, 0u);
      ++requests;
      ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    }
    loops.insert(loops.end(), ev.loops.begin(), ev.loops.end());
  }
  EXPECT_GE(core.stats().reverse_queries, 10u);
  EXPECT_GE(requests, 5u);
  ASSERT_GE(loops.size(), 4u);
  for (const auto& l : loops) {
    EXPECT_EQ(l.robot_a, 0u);
    EXPECT_EQ(l.robot_b, 1u);
    c.expect_true(l);
  }
}

// Each pair of two robots' keyframes is met by both robots' services (the newer keyframe's robot
// searches forward, the other searches that descriptor among its own keyframes): only the lower-
// numbered robot verifies it, so that one cloud crosses instead of one each way.
TEST(LoopCore, APairWithALowerRobotIsLeftToItAndItVerifiesItBothWays) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;  // inter-robot loops only
  params.peer_request_spacing = 0;
  LoopCore core0(params, 0u), core1(params, 1u);
  std::vector<LoopOut> loops0, loops1;
  size_t asked_by_1 = 0;
  std::set<uint32_t> asked_of_1;
  Nanos now{0};
  auto settle = [&](LoopCore& core, LoopEvents ev, std::vector<LoopOut>& loops, uint32_t me) {
    for (size_t i = 0; i < ev.requests.size(); ++i) {
      const CloudWanted r = ev.requests[i];
      EXPECT_NE(r.robot, me);
      if (me == 1) ++asked_by_1;
      if (me == 0) asked_of_1.insert(r.id);
      ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    }
    loops.insert(loops.end(), ev.loops.begin(), ev.loops.end());
  };
  for (uint32_t k = 0; c.truth.count({0, k}) != 0 && c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(200);
    for (uint32_t r : {0u, 1u}) {
      LoopCore& own = r == 0 ? core0 : core1;
      settle(own, own.add_keyframe_data(c.keyframe(r, k), now), r == 0 ? loops0 : loops1, r);
      for (uint32_t to : {0u, 1u}) {  // every descriptor reaches both services
        LoopCore& core = to == 0 ? core0 : core1;
        settle(core, core.add_descriptor(c.descriptor(r, k, params), now), to == 0 ? loops0 : loops1, to);
      }
    }
  }
  EXPECT_EQ(asked_by_1, 0u) << "robot 1 asked robot 0 for clouds";
  EXPECT_TRUE(loops1.empty()) << "robot 1 verified pairs with robot 0";
  EXPECT_EQ(core1.stats().verified, 0u);
  EXPECT_GE(core1.stats().left_to_lower_robot, 10u);
  EXPECT_EQ(core0.stats().left_to_lower_robot, 0u);
  EXPECT_GE(core0.stats().reverse_queries, 10u);
  EXPECT_GE(asked_of_1.size(), 5u);
  ASSERT_GE(loops0.size(), 4u);
  for (const auto& l : loops0) {
    EXPECT_NE(l.robot_a, l.robot_b);
    c.expect_true(l);
  }
}

TEST(LoopCore, AnUnansweredRequestTimesOutWithoutBlockingOtherCandidates) {
  // Robot 2's service; robot 0 never answers, robot 1 does.
  const Circle c(30, 3);
  LoopParams params;
  params.exclude_recent = 1000;
  params.max_verify = 4;
  params.peer_request_spacing = 0;
  params.request_timeout = std::chrono::seconds(1);
  params.request_attempts = 1;  // given up at the first timeout
  params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 2u);
  std::vector<LoopOut> loops;
  size_t to_silent = 0;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({2, k}) != 0; ++k) {
    now += std::chrono::milliseconds(200);
    LoopEvents ev;
    for (uint32_t r : {0u, 1u}) ev.append(core.add_descriptor(c.descriptor(r, k, params), now));  // reverse searches
    ev.append(core.add_keyframe_data(c.keyframe(2, k), now));
    ev.append(core.add_descriptor(c.descriptor(2, k, params), now));
    for (const auto& r : ev.requests) {
      if (r.robot == 0) {
        ++to_silent;
        continue;
      }
      ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    }
    for (const auto& l : ev.loops) {
      loops.push_back(l);
      EXPECT_EQ(l.robot_a, 1u) << "a loop with the silent robot";
      c.expect_true(l);
    }
    core.tick(now);
  }
  EXPECT_GE(to_silent, 3u);
  EXPECT_GE(loops.size(), 3u) << "loops with the answering robot went ahead";
  core.tick(now + std::chrono::seconds(2));
  EXPECT_EQ(core.pending_requests(), 0u);
  EXPECT_EQ(core.stats().timed_out, to_silent);
  EXPECT_EQ(core.stats().requests_abandoned, to_silent);
}

// Inter-robot loops only, every candidate's cloud asked for; requests time out after 1 s and are
// asked again 1 s later, `attempts` times in all.
LoopParams retrying(int attempts) {
  LoopParams p;
  p.exclude_recent = 1000;
  p.peer_request_spacing = 0;
  p.request_timeout = std::chrono::seconds(1);
  p.request_retry = std::chrono::seconds(1);
  p.request_attempts = attempts;
  p.lower_robot_verifies = false;  // robot 1's service verifies its pairs with robot 0 too
  return p;
}

// The link to the peer drops while its clouds are asked for (or its service does not hold a keyframe
// yet): the requests are parked, asked again once the peer is back in reach, and their loops found.
TEST(LoopCore, UnansweredRequestsAreAskedAgainWhenTheOwnerIsBackInReach) {
  const Circle c(30, 2);
  const LoopParams params = retrying(3);
  LoopCore core(params, 1u);
  bool in_reach = true;
  core.set_reachable([&](uint32_t) { return in_reach; });
  std::set<uint32_t> lost, not_held;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(10);
    LoopEvents ev = c.feed_step(core, k, params, now);
    EXPECT_TRUE(ev.loops.empty());
    for (const auto& r : ev.requests) {
      // Every other request is lost on the radio; the rest are answered "not held yet".
      if (r.id % 2 == 0) {
        lost.insert(r.id);
      } else {
        not_held.insert(r.id);
        core.on_cloud_missing(r.robot, r.id, now);
      }
    }
  }
  ASSERT_GE(lost.size() + not_held.size(), 4u);
  in_reach = false;  // the peer has gone: nothing is asked again
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(2)).requests.empty());
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(2)).requests.empty());
  EXPECT_EQ(core.pending_requests(), 0u);
  // A late answer to a parked request is used (and that request is not asked again).
  const uint32_t late = *lost.begin();
  std::vector<LoopOut> loops = core.on_cloud(0, late, c.clouds.at({0, late}), now).loops;
  EXPECT_EQ(core.stats().replies, 1u);
  EXPECT_EQ(core.stats().replies_unexpected, 0u);
  in_reach = true;  // back: every other parked request is asked again, once
  const LoopEvents again = core.tick(now += std::chrono::seconds(1));
  std::set<uint32_t> asked;
  for (const auto& r : again.requests) asked.insert(r.id);
  std::set<uint32_t> all = lost;
  all.insert(not_held.begin(), not_held.end());
  all.erase(late);
  EXPECT_EQ(asked, all);
  EXPECT_EQ(core.stats().requests_retried, all.size());
  for (const auto& r : again.requests) {
    for (const auto& l : core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now).loops) loops.push_back(l);
  }
  ASSERT_GE(loops.size(), 3u);
  for (const auto& l : loops) c.expect_true(l);
  EXPECT_EQ(core.stats().requests_abandoned, 0u);
}

TEST(LoopCore, ARequestIsAbandonedAfterItsLastAttempt) {
  const Circle c(16, 2);
  const LoopParams params = retrying(2);
  LoopCore core(params, 1u);
  size_t first = 0;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    LoopEvents ev = c.feed_step(core, k, params, now);
    first += ev.requests.size();
  }
  ASSERT_GE(first, 2u);
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(2)).requests.empty());        // timed out: parked
  EXPECT_EQ(core.tick(now += std::chrono::seconds(1)).requests.size(), first);   // second attempt
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(2)).requests.empty());        // timed out again
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(5)).requests.empty());        // no third
  EXPECT_EQ(core.stats().timed_out, 2 * first);
  EXPECT_EQ(core.stats().requests_abandoned, first);
  EXPECT_EQ(core.pending_requests(), 0u);
}

// Neighbouring keyframes of a peer close the same loop: with a request spacing of 5 keyframes, no
// two requested clouds of the peer are closer than that, and loops are still found.
TEST(LoopCore, PeerCloudRequestsAreSpacedAlongThePeersKeyframes) {
  const Circle c(30, 2);
  LoopParams params;
  params.exclude_recent = 1000;
  params.peer_request_spacing = 5;
  params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  std::vector<uint32_t> asked;
  std::vector<LoopOut> loops;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(200);
    LoopEvents ev = c.feed_step(core, k, params, now);
    for (const auto& r : ev.requests) {
      asked.push_back(r.id);
      ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
    }
    for (const auto& l : ev.loops) {
      if (!l.withdrawn) loops.push_back(l);
    }
  }
  std::sort(asked.begin(), asked.end());
  for (size_t i = 1; i < asked.size(); ++i) EXPECT_GT(asked[i] - asked[i - 1], 5u);
  EXPECT_GE(asked.size(), 2u);
  // Candidates next to a requested keyframe are verified against its cloud (no second request),
  // started from the offset in the peer's pose hints: the loops they give are true ones too.
  EXPECT_GE(core.stats().verified_with_neighbour, 5u);
  EXPECT_GT(loops.size(), asked.size());
  for (const LoopOut& l : loops) {
    EXPECT_EQ(l.robot_a, 0u);
    EXPECT_TRUE(std::binary_search(asked.begin(), asked.end(), l.keyframe_a)) << "a loop to a cloud never received";
    c.expect_true(l);
  }
}

// A candidate is only verified against a neighbour's cloud that starts registration within
// reaim_max_m of it; farther ones are left, without a request of their own either.
TEST(LoopCore, ACandidateIsNotReAimedAtANeighbourBeyondTheLimit) {
  const Circle c(30, 2);  // keyframes 2 m apart: with a spacing of 5, neighbours up to 10 m away
  std::vector<Verification> open_seen, gated_seen;
  std::vector<LoopOut> gated_loops;
  auto run = [&](double limit, std::vector<Verification>& seen, std::vector<LoopOut>& loops) {
    LoopParams params;
    params.exclude_recent = 1000;
    params.peer_request_spacing = 5;
    params.reaim_max_m = limit;
    params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too
    LoopCore core(params, 1u);
    Nanos now{0};
    for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
      now += std::chrono::milliseconds(200);
      LoopEvents ev = c.feed_step(core, k, params, now);
      for (size_t i = 0; i < ev.requests.size(); ++i) {
        const CloudWanted r = ev.requests[i];
        ev.append(core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now));
      }
      seen.insert(seen.end(), ev.verifications.begin(), ev.verifications.end());
      for (const auto& l : ev.loops) {
        if (!l.withdrawn) loops.push_back(l);
      }
    }
    return core.stats();
  };
  std::vector<LoopOut> open_loops;
  const LoopStats open = run(0, open_seen, open_loops);
  const LoopStats gated = run(3, gated_seen, gated_loops);
  EXPECT_EQ(open.reaim_too_far, 0u);
  EXPECT_TRUE(std::any_of(open_seen.begin(), open_seen.end(), [](const Verification& v) { return v.guess_m > 3; }))
      << "no neighbour beyond 3 m without the limit: the test shows nothing";
  EXPECT_GE(gated.reaim_too_far, 1u);
  EXPECT_LT(gated.verified, open.verified);
  EXPECT_EQ(gated.requests, open.requests);
  for (const Verification& v : gated_seen) EXPECT_LE(v.guess_m, 3.0) << v.candidate_id << " for " << v.query_id;
  EXPECT_GE(gated_loops.size(), 2u);
  for (const LoopOut& l : gated_loops) c.expect_true(l);
}

// A peer passes a place this robot saw while the two are out of range of each other: its candidates
// wait, parked, and are asked for once the peer is back in reach, so that their loops are found then.
TEST(LoopCore, CandidatesOfAnUnreachableOwnerAreAskedForWhenItIsBackInReach) {
  const Circle c(16, 2);
  LoopParams params;
  params.exclude_recent = 1000;
  params.lower_robot_verifies = false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
  LoopCore core(params, 1u);
  bool in_reach = false;
  core.set_reachable([&](uint32_t robot) { return robot != 0 || in_reach; });
  size_t requests = 0;
  Nanos now{0};
  for (uint32_t k = 0; c.truth.count({1, k}) != 0; ++k) {
    now += std::chrono::milliseconds(10);
    core.add_descriptor(c.descriptor(0, k, params), now);
    core.add_keyframe_data(c.keyframe(1, k), now);
    requests += core.add_descriptor(c.descriptor(1, k, params), now).requests.size();
    requests += core.tick(now).requests.size();
  }
  EXPECT_EQ(requests, 0u);  // nothing asked of an owner out of range
  EXPECT_EQ(core.pending_requests(), 0u);
  const uint64_t parked = core.stats().unreachable;
  ASSERT_GE(parked, 2u);
  in_reach = true;  // back in range: each parked request is asked once, and its loops are found
  const LoopEvents asked = core.tick(now += std::chrono::milliseconds(10));
  EXPECT_EQ(asked.requests.size(), parked);
  EXPECT_TRUE(core.tick(now += std::chrono::milliseconds(10)).requests.empty());
  std::vector<LoopOut> loops;
  for (const auto& r : asked.requests) {
    EXPECT_EQ(r.robot, 0u);
    for (const auto& l : core.on_cloud(r.robot, r.id, c.clouds.at({r.robot, r.id}), now).loops) loops.push_back(l);
  }
  ASSERT_GE(loops.size(), 2u);
  for (const auto& l : loops) c.expect_true(l);
  EXPECT_EQ(core.stats().requests, parked);
  EXPECT_EQ(core.stats().replies, parked);
  EXPECT_EQ(core.stats().requests_abandoned, 0u);
}

}  // namespace
}  // namespace cdc::loops
