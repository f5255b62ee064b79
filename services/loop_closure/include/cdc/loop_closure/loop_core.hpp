// The loop-closure service's synchronous core: Scan Context retrieval over every robot's
// keyframe descriptors, geometric verification (GICP from the descriptor's yaw), and PCM over each
// robot pair's inter-robot loops. Decisions are stable: a published loop is only ever retracted
// explicitly (a withdrawal).
//
// Event-driven, no I/O and no clock of its own. The keyframes whose clouds are held locally come
// in with add_keyframe_data (with their odometry); descriptors of any robot with add_descriptor.
// A descriptor of a robot this core queries for starts a search; a candidate whose cloud is not
// held locally becomes a cloud request (returned to the caller and answered with on_cloud or
// on_cloud_missing; tick parks one past its deadline or not answered with a cloud and asks again
// while the owner is in reach, a few times), and its verification waits while the other
// candidates go on. Robots whose odometry is not held locally are chained through the
// descriptors' pose hints with a nominal noise model (PCM needs both robots' odometry). A peer's
// descriptor is also searched among this robot's own keyframes (a reverse search), so that places
// both robots saw are found when the peer's descriptors arrive, whichever robot passed first.
#pragma once

#include "cdc/lidar/scan_context.hpp"
#include "cdc/loop_closure/cloud_requests.hpp"
#include "cdc/loop_closure/cloud_store.hpp"
#include "cdc/loop_closure/loop_types.hpp"
#include "cdc/loop_closure/pairwise_consistency.hpp"
#include "cdc/loop_closure/retrieval.hpp"
#include "cdc/loop_closure/verifier.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <utility>
#include <vector>

namespace cdc::loops {

// How the core routed candidates whose cloud is not held.
struct RoutingStats {
  uint64_t verified_with_neighbour = 0;  // candidates sent to a neighbouring keyframe's cloud (held or requested)
  uint64_t reaim_too_far = 0;            // candidates whose neighbouring clouds were all beyond reaim_max_m
};

// Every part's counters in one.
struct LoopStats : RetrievalStats, RequestStats, CloudStoreStats, VerificationStats, PcmStats, RoutingStats {};

// What a cloud reply is to the core (LoopCore::reply_use).
enum class ReplyUse {
  kCloud,        // a cloud it waits for: hand it to on_cloud
  kNotHeld,      // its owner does not hold the keyframe yet: on_cloud_missing (asked again later)
  kDuplicate,    // the cloud is held already: the other answer to a request asked twice (drop it)
  kUnrequested,  // answers no open request of this robot (reject it)
};

// The parts composed: Retrieval finds candidates, each is verified at once when its cloud is held
// (CloudStore), re-aimed at a neighbour's cloud or requested otherwise (CloudRequests), verified
// (Verifier), and its loop judged against the others (PairwiseConsistency).
class LoopCore {
 public:
  // `query_robot`: only this robot's descriptors start searches (a robot's service); none: every
  // robot's (the offline tool, which holds everything).
  explicit LoopCore(const LoopParams& params, std::optional<uint32_t> query_robot = std::nullopt);

  // Whether a robot can be asked for a cloud now (its owner is in range). Default: always.
  void set_reachable(std::function<bool(uint32_t robot)> reachable) { requests_.set_reachable(std::move(reachable)); }

  // A keyframe whose cloud is held here, with its odometry. Runs the search of its descriptor if
  // that came first.
  LoopEvents add_keyframe_data(KeyframeIn kf, Nanos now);
  // A descriptor of any robot's keyframe; searches when it is the query robot's.
  LoopEvents add_descriptor(DescriptorIn d, Nanos now);
  // A requested cloud arrived (keyframe frame; also one answering an earlier attempt of a request
  // asked again): verifications waiting for it run now.
  LoopEvents on_cloud(uint32_t robot, uint32_t id, std::vector<Eigen::Vector3f> cloud, Nanos now);
  // The owner answered that it does not have the keyframe (yet): asked again later (request_attempts).
  void on_cloud_missing(uint32_t robot, uint32_t id, Nanos now) { requests_.missing({robot, id}, now); }
  // Requests past their deadline are parked to be asked again (or abandoned after request_attempts);
  // parked ones whose owner is in reach are asked again now (the returned requests).
  LoopEvents tick(Nanos now);

  // Offline convenience: keyframe data and its (quantised) descriptor in one call; every cloud is
  // local, so no requests arise.
  std::vector<LoopOut> add_keyframe(KeyframeIn kf);

  // A locally held cloud (downsampled), or null.
  const std::vector<Eigen::Vector3f>* cloud(uint32_t robot, uint32_t id) const { return clouds_.find({robot, id}); }
  size_t pending_requests() const noexcept { return requests_.pending(); }
  size_t parked_requests() const noexcept { return requests_.parked(); }  // waiting to be asked (again)
  // Requested and not yet answered with a cloud: pending, or parked to be asked again.
  bool is_wanted(uint32_t robot, uint32_t id) const { return requests_.wanted({robot, id}); }
  // How to take a reply from `robot` about its keyframe `id`; `found`: it carries the cloud. A late
  // answer to an earlier attempt of a request asked again is as good as the awaited one.
  ReplyUse reply_use(uint32_t robot, uint32_t id, bool found) const;
  LoopStats stats() const;
  size_t keyframes() const noexcept { return retrieval_.size(); }
  const lidar::ScanContextDatabase& database() const noexcept { return retrieval_.database(); }

 private:
  // The keyframe's Scan Contexts from beside it (lane_views_m), in wire form.
  std::vector<ShiftedView> lane_views(const std::vector<Eigen::Vector3f>& cloud) const;
  // A candidate from retrieval: verified now when its cloud is held, else verified against a
  // neighbour's cloud or made to wait for its own (CloudRequests).
  void route(const VerificationJob& job, Nanos now, LoopEvents& out);
  void route_to_neighbour(const VerificationJob& neighbour, Nanos now, LoopEvents& out);
  // Whether the pair is new: each (query, candidate) pair is verified, or waits for its cloud, once.
  bool first_try(const VerificationJob& job) { return tried_.insert({job.query, job.candidate}).second; }
  LoopEvents verify(const VerificationJob& job);

  LoopParams p_;
  Retrieval retrieval_;
  CloudStore clouds_;
  CloudRequests requests_;
  Verifier verifier_;
  PairwiseConsistency pcm_;
  std::set<std::pair<KeyframeId, KeyframeId>> tried_;  // (query, candidate) verified or waiting for a cloud
  RoutingStats routing_;
};

// Scan Context on the wire and back, so that every decision uses what peers receive.
lidar::ScanContext wire_form(const lidar::ScanContext& sc);

}  // namespace cdc::loops
