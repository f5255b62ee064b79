// The cloud-request protocol of a robot's loop-closure service: a candidate whose cloud is held by
// its owner (a peer) is verified once that cloud arrives. One request per cloud gathers every
// verification waiting for it. A request is pending while its answer is expected (until
// request_timeout) and parked while it waits to be asked (again): its owner out of reach, no answer
// in time, or the owner not holding the keyframe yet; a parked request is asked again from
// request_retry on while its owner is in reach, request_attempts times in all, and then abandoned.
// Requests are spaced along each peer's keyframes (peer_request_spacing): a candidate next to a
// keyframe whose cloud is held or requested is re-aimed at it, started from the offset between the
// two in the peer's pose hints. Synchronous, no I/O and no clock of its own.
#pragma once

#include "cdc/loop_closure/loop_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <vector>

namespace cdc::loops {

struct RequestStats {
  // unreachable: requests parked at once because their owner was out of range (asked when it is back)
  uint64_t requests = 0, replies = 0, replies_unexpected = 0, missing = 0, timed_out = 0, unreachable = 0;
  uint64_t requests_retried = 0, requests_abandoned = 0;  // asked again; given up after request_attempts
  uint64_t skipped_near_requested = 0;  // candidates next to a peer keyframe whose cloud was requested
};

class CloudRequests {
 public:
  explicit CloudRequests(const LoopParams& params);

  // Whether a robot can be asked for a cloud now (its owner is in range). Default: always.
  void set_reachable(std::function<bool(uint32_t robot)> reachable) { reachable_ = std::move(reachable); }
  // A peer keyframe's pose (T_odom_keyframe in the peer's odometry), for re-aiming at a neighbour.
  void add_pose_hint(const KeyframeId& id, const Eigen::Isometry3d& pose_hint) { hints_[id] = pose_hint; }

  // The job re-aimed at the nearest keyframe within peer_request_spacing of its candidate whose cloud
  // is held (`held`) or requested, if that one starts registration within reaim_max_m; `too_far`:
  // there was such a keyframe, but only beyond reaim_max_m.
  struct Reaimed {
    std::optional<VerificationJob> job;
    bool too_far = false;
  };
  Reaimed reaim(const VerificationJob& job, const std::function<bool(const KeyframeId&)>& held) const;
  // Whether the candidate's cloud may be requested: not when a keyframe of its robot within
  // peer_request_spacing was requested (counted), unless a request for it is pending. Remembers it.
  bool reserve(const KeyframeId& candidate);
  // The job waits for its candidate's cloud: joins the request pending or parked for it, or makes
  // one, asked now (appended to `asked`) when the owner is in reach and parked until it is otherwise.
  void wait_for(const VerificationJob& job, Nanos now, std::vector<CloudWanted>& asked);

  // A cloud arrived (also one answering an earlier attempt of a request asked again): the jobs that
  // waited for it, or nullopt (counted) when none did.
  std::optional<std::vector<VerificationJob>> answered(const KeyframeId& id);
  // The owner answered that it does not hold the keyframe (yet): parked, or abandoned after its last
  // attempt. A parked request stays parked.
  void missing(const KeyframeId& id, Nanos now);
  // Requests past their deadline are parked (or abandoned after request_attempts); parked ones due
  // whose owner is in reach are asked again now (returned).
  std::vector<CloudWanted> tick(Nanos now);

  size_t pending() const noexcept { return pending_.size(); }
  size_t parked() const noexcept { return parked_.size(); }
  // Requested and not yet answered with a cloud: pending, or parked to be asked (again).
  bool wanted(const KeyframeId& id) const { return pending_.count(id) != 0 || parked_.count(id) != 0; }
  const RequestStats& stats() const noexcept { return stats_; }

 private:
  struct Request {
    Nanos deadline{0};  // pending: answer expected by; parked: ask again from
    std::vector<VerificationJob> jobs;
    int attempts = 1;
  };
  // A request not answered with a cloud: park it for another attempt, or abandon it.
  void park(const KeyframeId& id, Request r, Nanos now);
  void expire(Nanos now);
  void ask_parked(Nanos now, std::vector<CloudWanted>& asked);

  LoopParams p_;
  std::function<bool(uint32_t)> reachable_;
  std::map<uint32_t, std::set<uint32_t>> requested_;  // per peer: keyframes whose clouds were requested
  std::map<KeyframeId, Eigen::Isometry3d> hints_;     // peers' keyframes: T_odom_keyframe
  std::map<KeyframeId, Request> pending_;
  std::map<KeyframeId, Request> parked_;
  RequestStats stats_;
};

}  // namespace cdc::loops
