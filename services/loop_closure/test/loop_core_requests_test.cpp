// The loop-closure core's cloud requests on simulated scans: an unanswered request does not hold
// the others back, is asked again while its owner is in reach and abandoned after its last attempt;
// requests are spaced along a peer's keyframes, candidates re-aimed at a neighbour's cloud within a
// limit; an unreachable owner's candidates wait for it. Every loop published is true (1 m / 5 deg).
#include "circle_robots.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <vector>

namespace cdc::loops {
namespace {

TEST(LoopCore, AnUnansweredRequestTimesOutWithoutBlockingOtherCandidates) {
  // Robot 2's service; robot 0 never answers, robot 1 does.
  const Circle c(30, 3);
  LoopParams params;
  params.exclude_recent = 1000;
  params.max_verify = 4;
  params.peer_request_spacing = 0;
  params.request_timeout = std::chrono::seconds(1);
  params.request_attempts = 1;  // given up at the first timeout
  params.lower_robot_verifies =
      false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
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
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(2)).requests.empty());      // timed out: parked
  EXPECT_EQ(core.tick(now += std::chrono::seconds(1)).requests.size(), first);  // second attempt
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(2)).requests.empty());      // timed out again
  EXPECT_TRUE(core.tick(now += std::chrono::seconds(5)).requests.empty());      // no third
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
  params.lower_robot_verifies =
      false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
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
  params.lower_robot_verifies =
      false;  // this robot verifies its pairs with robot 0 too (see LoopCore.APairWithALowerRobot...)
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
