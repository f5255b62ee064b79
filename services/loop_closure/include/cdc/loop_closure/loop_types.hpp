// What goes into and comes out of the loop-closure core and its parts: parameters, keyframes and
// descriptors in, loops, cloud requests and verification records out.
#pragma once

#include "cdc/graph/pcm.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/lidar/scan_context.hpp"
#include "cdc/odometry/registration.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <cstdint>
#include <utility>
#include <vector>

namespace cdc::loops {

using Nanos = std::chrono::nanoseconds;

// Verification's registration: GICP from the retrieval's guess on 0.4 m voxel centroids, judged by
// the share of the query's points within 0.5 m of the candidate's (overlap) and their mean squared
// distance (fitness).
inline odometry::RegistrationSettings verification_registration() {
  odometry::RegistrationSettings s = odometry::RegistrationSettings::gicp();
  s.max_correspondence_m = 2.0;
  // A true loop converges in 2-9 iterations from the verification's guess; a false candidate mostly runs
  // to the limit and then fails on overlap. At 15 (against 40), cdc-loops run on the simulated KITTI 05
  // (900 scans) and 06 splits keeps the same 330 / 313 loops with the same errors, in 22 % / 12 % less time.
  s.max_iterations = 15;
  s.neighbours = 20;  // points per covariance (10 leaves a sparse sweep's ground line-like: tilt errors)
  s.voxel_m = 0.4;    // both clouds reduced before registration (0: none)
  s.inlier_distance_m = 0.5;
  // GICP Hessian at the solution -> information. 0.03 puts sigma at about 1.4x the error measured on the
  // simulated KITTI-05 loops (cdc-loops run: 8 / 3 / 6 mm, 0.05 / 0.07 / 0.007 deg RMS, x y z, roll pitch yaw).
  s.information_scale = 0.03;
  return s;
}

struct LoopParams {
  lidar::ScanContextParams scan_context;
  size_t knn = 10;                // ring-key neighbours examined
  double max_sc_distance = 0.35;  // Scan Context distance for a candidate
  uint32_t exclude_recent = 50;   // same-robot keyframes too recent to close a loop with
  // A same-robot candidate is only verified when the robot's own odometry puts it within
  // intra_gate_m + intra_gate_per_m * (path driven between the two) of the query: Scan Context
  // confuses look-alike streets, and each verification costs a registration. 0: no gate.
  double intra_gate_m = 15, intra_gate_per_m = 0.05;
  size_t max_verify = 2;  // candidates verified per keyframe
  // Each keyframe held here is also described from virtual sensors this far to its left (+) and right
  // (-) [m] (lidar::make_scan_context from a sensor): a place met driving the other way on the
  // opposite lane lies a lane aside, where Scan Context distances are 0.45-0.7 against 0.02-0.1 from
  // the view beside it (simulated KITTI 05, robot 1 reversed 3.5 m aside). Empty: none.
  std::vector<double> lane_views_m = {3.5, -3.5};
  odometry::RegistrationSettings registration = verification_registration();
  // The verification's guess is moved along the candidate's up to put the two clouds' grounds
  // (lidar::ground_height) level when the guess leaves them further apart than this [m]: two passes of
  // one place at different heights (a sensor mounted higher; elevations that disagree between passes,
  // 2-5 m in places of KITTI 08's ground truth) start registration that far off in height, beyond
  // the correspondence distance, where it slides to a wrong height or fails. 0: always level them.
  double ground_guess_min_m = 1.0;
  double max_fitness = 0.15;  // [m^2] mean squared inlier distance
  double min_overlap = 0.55;
  // The front-ends hold roll and pitch with gravity, so a loop's tilt (two sparse sweeps seen from
  // different places, whose ground rings disagree) is the weakest part of it: its roll/pitch
  // information is scaled by this in the query keyframe's level frame (graph::level_information).
  // 1: as registered (robots whose odometry does not hold its tilt: LiDAR-only).
  double tilt_information_scale = 0.01;
  // The registration's information matches its own error (verification_registration());
  // a loop enters the graph with that x this. The pose graph does not model the odometry's slowly varying
  // errors (a gravity-levelled front-end's tilt wanders by ~0.1 deg around a bias of 0.2-0.3 deg), so a
  // loop held to its 1 cm bends the robots' trajectories to fit: on simulated KITTI-05 (0.2 deg LiDAR
  // elevation error) the central's solution is worse than odometry at 1 (robot 0: 0.164 vs 0.100 m ATE).
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
  size_t cloud_cache = 256;  // peers' clouds kept after verification (least recently received dropped)
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
  std::vector<Eigen::Vector3f> cloud;                        // keyframe frame, sensor at the origin
};

struct DescriptorIn {
  uint32_t robot = 0, id = 0;
  lidar::ScanContext context;                                   // as received (dequantised)
  Eigen::Isometry3d pose_hint = Eigen::Isometry3d::Identity();  // T_odom_keyframe
};

// A keyframe's Scan Context as seen from a virtual sensor at `sensor` (keyframe frame).
struct ShiftedView {
  lidar::ScanContext context;
  Eigen::Vector3d sensor = Eigen::Vector3d::Zero();
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
  std::vector<LoopOut> loops;         // newly accepted loops and withdrawals, in order
  std::vector<CloudWanted> requests;  // clouds to ask their owners for
  std::vector<Verification> verifications;
  void append(LoopEvents&& o);
};

using KeyframeId = std::pair<uint32_t, uint32_t>;  // (robot, keyframe)

// A registration to run: the query (one of this robot's keyframes) against a candidate (the other
// keyframe), started from `guess`.
struct VerificationJob {
  KeyframeId query, candidate;
  Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();  // T_candidate_query to start from
};

}  // namespace cdc::loops
