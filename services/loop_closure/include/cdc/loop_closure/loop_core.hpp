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

#include "cdc/graph/pcm.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/lidar/registration.hpp"
#include "cdc/lidar/scan_context.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

namespace cdc::loops {

using Nanos = std::chrono::nanoseconds;

struct LoopParams {
  lidar::ScanContextParams scan_context;
  size_t knn = 10;                 // ring-key neighbours examined
  double max_sc_distance = 0.35;   // Scan Context distance for a candidate
  uint32_t exclude_recent = 50;    // same-robot keyframes too recent to close a loop with
  // A same-robot candidate is only verified when the robot's own odometry puts it within
  // intra_gate_m + intra_gate_per_m * (path driven between the two) of the query: Scan Context
  // confuses look-alike streets, and each verification costs a registration. 0: no gate.
  double intra_gate_m = 15, intra_gate_per_m = 0.05;
  size_t max_verify = 2;           // candidates verified per keyframe
  lidar::RegistrationParams registration;
  double max_fitness = 0.15;       // [m^2] mean squared inlier distance
  double min_overlap = 0.55;
  // The front-ends hold roll and pitch with gravity, so a loop's tilt (two sparse sweeps seen from
  // different places, whose ground rings disagree) is the weakest part of it: its roll/pitch
  // information is scaled by this in the query keyframe's level frame (graph::level_information).
  // 1: as registered (robots whose odometry does not hold its tilt: LiDAR-only).
  double tilt_information_scale = 0.01;
  // The registration's information matches its own error (lidar::RegistrationParams::information_scale);
  // a loop enters the graph with that x this. The pose graph does not model the odometry's slowly varying
  // errors (a gravity-levelled front-end's tilt wanders by ~0.1 deg around a bias of 0.2-0.3 deg), so a
  // loop held to its 1 cm bends the robots' trajectories to fit: on simulated KITTI-05 (0.2 deg LiDAR
  // elevation error) the central's solution was worse than odometry at 1 (robot 0: 0.164 vs 0.100 m ATE).
  double loop_information_scale = 0.03;
  graph::PcmOptions pcm;
  // Inter-robot loops are published from a consistent set at least this large, spanning at least two
  // keyframes of each robot (when this is 2 or more).
  size_t min_inter_support = 2;
  Nanos request_timeout = std::chrono::seconds(10);  // an unanswered cloud request is given up after this
  // A request that timed out, or that its owner could not answer yet (the keyframe had not reached its
  // own loop-closure service), is asked again after request_retry while the owner is in reach, up to
  // request_attempts requests in all; then its verifications are dropped.
  int request_attempts = 3;
  Nanos request_retry = std::chrono::seconds(5);
  size_t cloud_cache = 256;        // peers' clouds kept after verification (least recently received dropped)
  // Clouds kept ready for registration (k-d tree and GICP covariances, ~1 MB each), most recently used
  // first: the verifications of one query, or against one requested cloud, come in bursts. 0: none.
  size_t prepared_clouds = 8;
  // A peer's cloud is not requested when one within this many of that peer's keyframes was requested
  // already: neighbouring keyframes (1 m apart) close the same loop, and each request is a whole cloud
  // on the radio. The candidate is verified against that neighbour's cloud instead (held or on its
  // way), started from the offset between the two in the peer's pose hints. 0: request every candidate.
  uint32_t peer_request_spacing = 10;
  // A candidate is only re-aimed at a neighbour whose cloud starts registration within this many
  // metres of the query (the offset in the peer's pose hints): sweeps that far apart rarely
  // overlap enough (cdc-bench-loops --wire, KITTI 05 and 09: none of 244 beyond 16 m passed, 4 of
  // 70 at 14-16 m). Beyond it the candidate is left (no request either: the neighbour's loop stands
  // for the place). 0: no limit.
  double reaim_max_m = 16;
  // A robot's service (query robot) leaves every pair of keyframes with a lower-numbered robot to
  // that robot: each pair is met twice, by the newer keyframe's robot searching forward and by the
  // older one's searching the newer descriptor among its own (reverse), and verifying it on both
  // sides sends a cloud each way for one loop. The lower robot verifies it, forward or reverse.
  bool lower_robot_verifies = true;
  // Nominal odometry noise for robots chained through pose hints: per step, sigma = a + b * length.
  double hint_sigma_m = 0.02, hint_sigma_m_per_m = 0.01;
  double hint_sigma_rad = 0.002, hint_sigma_rad_per_m = 0.0005;
};

struct KeyframeIn {
  uint32_t robot = 0, id = 0;
  Eigen::Isometry3d T_prev = Eigen::Isometry3d::Identity();  // relative odometry from id - 1
  graph::Matrix6d information = graph::Matrix6d::Identity();
  Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();  // T_odom_keyframe (its tilt: where up is)
  std::vector<Eigen::Vector3f> cloud;                          // keyframe frame, sensor at the origin
};

struct DescriptorIn {
  uint32_t robot = 0, id = 0;
  lidar::ScanContext context;       // as received (dequantised)
  Eigen::Isometry3d pose_hint = Eigen::Isometry3d::Identity();  // T_odom_keyframe
};

struct LoopOut {
  uint32_t robot_a = 0, keyframe_a = 0, robot_b = 0, keyframe_b = 0;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  graph::Matrix6d information = graph::Matrix6d::Identity();
  double fitness = 0;
  bool withdrawn = false;
};

struct CloudWanted {
  uint32_t robot = 0, id = 0;
};

// One geometric verification and its outcome (for the service's debug log).
struct Verification {
  uint32_t query_robot = 0, query_id = 0, candidate_robot = 0, candidate_id = 0;
  bool converged = false, passed = false;
  double fitness = 0, overlap = 0;
  double guess_m = 0, correction_m = 0;  // |t| of the starting guess, and how far registration moved it
};

struct LoopEvents {
  std::vector<LoopOut> loops;           // newly accepted loops and withdrawals, in order
  std::vector<CloudWanted> requests;    // clouds to ask their owners for
  std::vector<Verification> verifications;
  void append(LoopEvents&& o);
};

struct LoopStats {
  uint64_t queries = 0, candidates = 0, verified = 0, verification_failed = 0;
  // Why verifications failed (each failure counts under its first reason).
  uint64_t failed_not_converged = 0, failed_fitness = 0, failed_overlap = 0;
  uint64_t intra_accepted = 0, intra_inconsistent = 0, inter_proposed = 0, inter_accepted = 0, withdrawn = 0;
  // unreachable: requests parked at once because their owner was out of range (asked when it is back)
  uint64_t requests = 0, replies = 0, replies_unexpected = 0, missing = 0, timed_out = 0, unreachable = 0;
  uint64_t requests_retried = 0, requests_abandoned = 0;  // asked again; given up after request_attempts
  uint64_t duplicate_descriptors = 0, deferred_dropped = 0;
  uint64_t reverse_queries = 0;  // peers' descriptors searched among this robot's own keyframes
  uint64_t intra_gated = 0;      // same-robot candidates too far by the robot's odometry (not verified)
  uint64_t skipped_near_requested = 0;  // candidates next to a peer keyframe whose cloud was requested
  uint64_t left_to_lower_robot = 0;     // candidates with a lower-numbered robot, verified by that robot
  uint64_t verified_with_neighbour = 0; // candidates sent to a neighbouring keyframe's cloud (held or requested)
  uint64_t reaim_too_far = 0;           // candidates whose neighbouring clouds were all beyond reaim_max_m
  uint64_t prepared = 0, prepared_reused = 0;  // clouds made ready for registration; look-ups (two per registration) that found one ready
};

class LoopCore {
 public:
  // `query_robot`: only this robot's descriptors start searches (a robot's service); none: every
  // robot's (the offline tool, which holds everything).
  explicit LoopCore(const LoopParams& params, std::optional<uint32_t> query_robot = std::nullopt);

  // Whether a robot can be asked for a cloud now (its owner is in range). Default: always.
  void set_reachable(std::function<bool(uint32_t robot)> reachable) { reachable_ = std::move(reachable); }

  // A keyframe whose cloud is held here, with its odometry. Runs the search of its descriptor if
  // that came first.
  LoopEvents add_keyframe_data(KeyframeIn kf, Nanos now);
  // A descriptor of any robot's keyframe; searches when it is the query robot's.
  LoopEvents add_descriptor(DescriptorIn d, Nanos now);
  // A requested cloud arrived (keyframe frame; also one answering an earlier attempt of a request
  // asked again): verifications waiting for it run now.
  LoopEvents on_cloud(uint32_t robot, uint32_t id, std::vector<Eigen::Vector3f> cloud, Nanos now);
  // The owner answered that it does not have the keyframe (yet): asked again later (request_attempts).
  void on_cloud_missing(uint32_t robot, uint32_t id, Nanos now);
  // Requests past their deadline are parked to be asked again (or abandoned after request_attempts);
  // parked ones whose owner is in reach are asked again now (the returned requests).
  LoopEvents tick(Nanos now);

  // Offline convenience: keyframe data and its (quantised) descriptor in one call; every cloud is
  // local, so no requests arise.
  std::vector<LoopOut> add_keyframe(KeyframeIn kf);

  // A locally held cloud (downsampled), or null.
  const std::vector<Eigen::Vector3f>* cloud(uint32_t robot, uint32_t id) const;
  size_t pending_requests() const noexcept { return pending_.size(); }
  size_t parked_requests() const noexcept { return parked_.size(); }  // waiting to be asked (again)
  // Requested and not yet answered with a cloud: pending, or parked to be asked again.
  bool is_wanted(uint32_t robot, uint32_t id) const { return pending_.count({robot, id}) != 0 || parked_.count({robot, id}) != 0; }
  const LoopStats& stats() const noexcept { return stats_; }
  size_t keyframes() const noexcept { return db_.size(); }
  const lidar::ScanContextDatabase& database() const noexcept { return db_; }

 private:
  using Id = std::pair<uint32_t, uint32_t>;  // (robot, keyframe)
  struct Job {
    Id query, candidate;
    Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();  // T_candidate_query to start from
  };
  struct Pending {
    Nanos deadline{0};  // pending: answer expected by; parked: ask again from
    std::vector<Job> jobs;
    int attempts = 1;
  };
  // A request not answered with a cloud: park it for another attempt, or abandon it.
  void park(const Id& candidate, Pending p, Nanos now);
  // The job waits for its candidate's cloud: joins a request pending or parked for it, or makes one,
  // asked now (in `out`) when the owner is in reach and parked until it is otherwise.
  void wait_for_cloud(const Job& job, Nanos now, LoopEvents& out);
  LoopEvents verify(const Job& job);
  // A keyframe of the candidate's robot within peer_request_spacing of it whose cloud is held or
  // requested, with the job re-aimed at it (the offset from the robot's pose hints), if any within
  // reaim_max_m; `too_far` says whether there was one but only beyond that.
  std::optional<Job> neighbour_job(const Job& job, bool& too_far) const;
  LoopEvents update_pcm(uint32_t robot_a, uint32_t robot_b);
  void add_odometry(uint32_t robot, uint32_t from, uint32_t to, const Eigen::Isometry3d& T, const graph::Matrix6d& info);

  LoopParams p_;
  std::map<uint32_t, std::set<uint32_t>> requested_;  // per peer: keyframes whose clouds were requested
  std::optional<uint32_t> query_robot_;
  std::function<bool(uint32_t)> reachable_;
  lidar::ScanContextDatabase db_;
  std::vector<Id> owner_;                                  // db id -> keyframe
  std::set<Id> described_;                                 // keyframes with a descriptor
  std::map<Id, std::vector<Eigen::Vector3f>> clouds_;      // downsampled, local and cached
  std::set<Id> local_;                                     // keyframes whose data is held here
  std::deque<Id> cache_order_;                             // cached peer clouds, oldest first
  // Clouds ready for registration, most recently used first (prepared_clouds of them).
  std::deque<std::pair<Id, std::shared_ptr<const lidar::PreparedCloud>>> prepared_;
  std::shared_ptr<const lidar::PreparedCloud> prepared(const Id& id, const std::vector<Eigen::Vector3f>& cloud);
  void set_cloud(const Id& id, std::vector<Eigen::Vector3f> cloud);  // also drops a prepared one
  void drop_prepared(const Id& id);
  std::set<uint32_t> data_robots_;                         // robots with odometry from keyframe data
  struct Chained {
    Eigen::Isometry3d pose;  // in the robot's odometry frame (from its first keyframe here)
    double path_m = 0;       // distance driven since then
  };
  std::map<Id, Eigen::Vector3d> up_;                       // up in each local keyframe's frame
  std::map<Id, Chained> chained_;                          // keyframes with an unbroken odometry chain
  // Whether the robot's odometry allows a same-robot loop between these two keyframes (intra gate).
  bool intra_plausible(const Id& query, const Id& candidate) const;
  std::map<uint32_t, std::pair<uint32_t, Eigen::Isometry3d>> last_hint_;  // robot -> (id, pose hint)
  std::map<Id, Eigen::Isometry3d> hints_;                  // peers' keyframes: T_odom_keyframe
  std::set<std::pair<Id, Id>> tried_;                     // (query, candidate) verified or waiting for a cloud
  std::map<Id, Pending> pending_;                          // requested clouds
  std::map<Id, Pending> parked_;                           // unanswered requests waiting to be asked again
  std::map<Id, DescriptorIn> deferred_;                    // query descriptors waiting for their keyframe
  graph::PoseGraph odometry_;                              // every robot's odometry + inter loops
  std::map<std::pair<uint32_t, uint32_t>, std::vector<size_t>> inter_;  // robot pair -> factor ids
  std::map<size_t, LoopOut> proposed_;                     // factor id -> loop
  std::set<size_t> published_;                             // factor ids accepted and published
  LoopStats stats_;
};

// Scan Context on the wire and back, so that every decision uses what peers receive.
lidar::ScanContext wire_form(const lidar::ScanContext& sc);

}  // namespace cdc::loops
