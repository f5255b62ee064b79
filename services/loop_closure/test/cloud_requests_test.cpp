// The cloud-request protocol: one request per cloud, parked while its owner is out of reach or the
// answer does not come, asked again a few times, spaced along the peer's keyframes.
#include "cdc/loop_closure/cloud_requests.hpp"

#include "synthetic.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <set>
#include <vector>

namespace cdc::loops {
namespace {

using std::chrono::seconds;

VerificationJob job(uint32_t query_id, uint32_t peer, uint32_t candidate_id) {
  return VerificationJob{{0, query_id}, {peer, candidate_id}, Eigen::Isometry3d::Identity()};
}

// Requests time out after 1 s and are asked again 1 s later, three times in all; every candidate's
// cloud may be requested.
LoopParams params() {
  LoopParams p;
  p.request_timeout = seconds(1);
  p.request_retry = seconds(1);
  p.request_attempts = 3;
  p.peer_request_spacing = 0;
  return p;
}

// Requests with one asked at time 0: robot 2's keyframe 7, for this robot's keyframe 1.
CloudRequests one_asked() {
  CloudRequests r(params());
  std::vector<CloudWanted> asked;
  r.wait_for(job(1, 2, 7), Nanos(0), asked);
  EXPECT_EQ(asked.size(), 1u);
  return r;
}

std::set<uint32_t> ids(const std::vector<CloudWanted>& asked) {
  std::set<uint32_t> out;
  for (const CloudWanted& c : asked) out.insert(c.id);
  return out;
}

TEST(CloudRequests, OneRequestPerCloudGathersEveryJobWaitingForIt) {
  CloudRequests r(params());
  std::vector<CloudWanted> asked;
  r.wait_for(job(1, 2, 7), Nanos(0), asked);
  r.wait_for(job(2, 2, 7), Nanos(0), asked);
  r.wait_for(job(2, 2, 8), Nanos(0), asked);
  ASSERT_EQ(asked.size(), 2u);
  EXPECT_EQ(asked[0].robot, 2u);
  EXPECT_EQ(ids(asked), (std::set<uint32_t>{7, 8}));
  EXPECT_EQ(r.pending(), 2u);
  EXPECT_TRUE(r.wanted({2, 7}));
  const auto jobs = r.answered({2, 7});
  ASSERT_TRUE(jobs.has_value());
  ASSERT_EQ(jobs->size(), 2u);
  EXPECT_EQ((*jobs)[0].query.second, 1u);
  EXPECT_EQ((*jobs)[1].query.second, 2u);
  EXPECT_FALSE(r.wanted({2, 7}));
  EXPECT_FALSE(r.answered({2, 7}).has_value()) << "answered already";
  EXPECT_EQ(r.stats().requests, 2u);
  EXPECT_EQ(r.stats().replies, 1u);
  EXPECT_EQ(r.stats().replies_unexpected, 1u);
}

TEST(CloudRequests, AnUnansweredRequestIsAskedAgainAndAbandonedAfterItsLastAttempt) {
  CloudRequests r = one_asked();
  Nanos now(0);
  EXPECT_TRUE(r.tick(now += seconds(1)).empty());  // timed out: parked
  EXPECT_EQ(r.parked(), 1u);
  EXPECT_TRUE(r.wanted({2, 7}));
  EXPECT_EQ(r.tick(now += seconds(1)).size(), 1u);  // second attempt
  EXPECT_TRUE(r.tick(now += seconds(1)).empty());
  EXPECT_EQ(r.tick(now += seconds(1)).size(), 1u);  // third
  EXPECT_TRUE(r.tick(now += seconds(1)).empty());   // timed out: abandoned
  EXPECT_TRUE(r.tick(now += seconds(10)).empty());
  EXPECT_FALSE(r.wanted({2, 7}));
  EXPECT_EQ(r.stats().timed_out, 3u);
  EXPECT_EQ(r.stats().requests, 3u);
  EXPECT_EQ(r.stats().requests_retried, 2u);
  EXPECT_EQ(r.stats().requests_abandoned, 1u);
}

TEST(CloudRequests, AnOwnerNotHoldingTheKeyframeYetIsAskedAgainLater) {
  CloudRequests r = one_asked();
  r.missing({2, 7}, Nanos(0));
  EXPECT_EQ(r.pending(), 0u);
  EXPECT_EQ(r.parked(), 1u);
  r.missing({2, 7}, Nanos(0));  // a parked request stays parked
  r.missing({2, 9}, Nanos(0));  // never asked
  EXPECT_EQ(r.stats().missing, 1u);
  EXPECT_EQ(r.stats().replies_unexpected, 2u);
  EXPECT_TRUE(r.tick(Nanos(0) + std::chrono::milliseconds(900)).empty());
  EXPECT_EQ(ids(r.tick(seconds(1))), (std::set<uint32_t>{7}));
  // A late answer to the first attempt, while the request is asked again, is as good.
  EXPECT_TRUE(r.answered({2, 7}).has_value());
  EXPECT_EQ(r.pending() + r.parked(), 0u);
}

TEST(CloudRequests, ARequestWaitsParkedWhileItsOwnerIsOutOfReach) {
  CloudRequests r(params());
  bool in_reach = false;
  r.set_reachable([&](uint32_t robot) { return robot != 2 || in_reach; });
  std::vector<CloudWanted> asked;
  r.wait_for(job(1, 2, 7), Nanos(0), asked);
  r.wait_for(job(1, 3, 4), Nanos(0), asked);
  EXPECT_EQ(ids(asked), (std::set<uint32_t>{4})) << "robot 3 is in reach";
  EXPECT_EQ(r.stats().unreachable, 1u);
  r.answered({3, 4});
  EXPECT_TRUE(r.tick(seconds(30)).empty());  // long out of reach: kept, attempts untouched
  in_reach = true;
  Nanos now = seconds(30);
  EXPECT_EQ(ids(r.tick(now)), (std::set<uint32_t>{7}));
  for (int attempt = 2; attempt <= 3; ++attempt) {  // all of its attempts are still to come
    EXPECT_TRUE(r.tick(now += seconds(1)).empty());
    EXPECT_EQ(r.tick(now += seconds(1)).size(), 1u) << "attempt " << attempt;
  }
  EXPECT_TRUE(r.tick(now += seconds(1)).empty());
  EXPECT_EQ(r.stats().requests_abandoned, 1u);
}

TEST(CloudRequests, RequestsAreSpacedAlongAPeersKeyframes) {
  LoopParams p = params();
  p.peer_request_spacing = 5;
  CloudRequests r(p);
  EXPECT_TRUE(r.reserve({2, 10}));
  EXPECT_FALSE(r.reserve({2, 14}));
  EXPECT_FALSE(r.reserve({2, 5}));
  EXPECT_TRUE(r.reserve({2, 16}));
  EXPECT_TRUE(r.reserve({3, 12})) << "another peer";
  std::vector<CloudWanted> asked;
  r.wait_for(job(1, 2, 10), Nanos(0), asked);
  EXPECT_TRUE(r.reserve({2, 10})) << "pending: its jobs join the request";
  EXPECT_EQ(r.stats().skipped_near_requested, 2u);
  p.peer_request_spacing = 0;
  CloudRequests every(p);
  EXPECT_TRUE(every.reserve({2, 10}));
  EXPECT_TRUE(every.reserve({2, 11}));
}

// Peer 2's keyframes 10 m apart along x; keyframes 10 (requested) and 20 (held) are the neighbours.
struct Neighbours {
  CloudRequests requests;
  std::set<KeyframeId> held{{2, 20}};
  explicit Neighbours(LoopParams p) : requests(p) {
    for (uint32_t id = 0; id <= 30; ++id) requests.add_pose_hint({2, id}, test::planar(10.0 * id, 0, 0));
    std::vector<CloudWanted> asked;
    for (uint32_t id : {10u, 20u}) {
      EXPECT_TRUE(requests.reserve({2, id}));
      requests.wait_for(job(0, 2, id), Nanos(0), asked);
    }
    requests.answered({2, 20});
  }
  CloudRequests::Reaimed reaim(uint32_t candidate) {
    return requests.reaim(job(1, 2, candidate), [&](const KeyframeId& id) { return held.count(id) != 0; });
  }
};

TEST(CloudRequests, ACandidateIsReAimedAtTheNearestRequestedNeighbour) {
  LoopParams p = params();
  p.peer_request_spacing = 5;
  p.reaim_max_m = 0;
  Neighbours n(p);
  const CloudRequests::Reaimed below = n.reaim(13);
  ASSERT_TRUE(below.job.has_value());
  EXPECT_EQ(below.job->candidate, (KeyframeId{2, 10}));
  EXPECT_EQ(below.job->query, (KeyframeId{0, 1}));
  // Started from the offset between the two in the peer's pose hints: T_10_13.
  EXPECT_TRUE(below.job->guess.isApprox(test::planar(30, 0, 0), 1e-12));
  const CloudRequests::Reaimed above = n.reaim(17);  // 20 is held
  ASSERT_TRUE(above.job.has_value());
  EXPECT_EQ(above.job->candidate, (KeyframeId{2, 20}));
  EXPECT_FALSE(n.reaim(10).job.has_value()) << "its own cloud";
  EXPECT_FALSE(n.reaim(26).job.has_value()) << "beyond the spacing";
  n.held.clear();
  EXPECT_FALSE(n.reaim(17).job.has_value()) << "20's cloud no longer held";
}

TEST(CloudRequests, ACandidateIsNotReAimedBeyondTheLimit) {
  LoopParams p = params();
  p.peer_request_spacing = 5;
  p.reaim_max_m = 25;
  Neighbours n(p);
  EXPECT_TRUE(n.reaim(12).job.has_value());        // 20 m
  const CloudRequests::Reaimed far = n.reaim(13);  // 30 m from 10 (20 is beyond the spacing)
  EXPECT_FALSE(far.job.has_value());
  EXPECT_TRUE(far.too_far);
  const CloudRequests::Reaimed one_near = n.reaim(18);  // 20 m from 20
  EXPECT_TRUE(one_near.job.has_value());
  EXPECT_FALSE(one_near.too_far);
  EXPECT_FALSE(n.reaim(26).too_far) << "no neighbour at all";
}

}  // namespace
}  // namespace cdc::loops
