// The peer optimiser's configuration and the records its core takes in and gives out (the node
// converts them from and to DDS messages; cdc-peer-replay builds them from a g2o graph).
#pragma once

#include "cdc/geometry/fusion.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/peer_optimiser/rtdos.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace cdc::peer {

using graph::Key;
using graph::Matrix6d;

// Own keyframes by id with a pose each (T_world_keyframe unless said otherwise).
using KeyframePoses = std::vector<std::pair<uint32_t, Eigen::Isometry3d>>;

struct PeerConfig {
  uint32_t robot = 0;
  uint32_t robot_count = 3;
  RtdosParams rtdos;
  geometry::FusionThresholds fusion;
  double peer_range_m = 1e9;                            // separators go only to peers closer than this
  Nanos round_period{std::chrono::milliseconds(200)};   // distributed optimisation rounds
  Nanos resend_grace{std::chrono::milliseconds(1500)};  // unacknowledged this long: re-send
  Nanos resend_period{std::chrono::milliseconds(500)};
  int distributed_iterations = 5;
  // Each round moves the own keyframes this fraction of the way to the block's solution (in each
  // pose's tangent space). Every robot solves at once with its peers' last separators held fixed
  // (block Jacobi); taken whole (1.0), two coupled robots each jump onto the other's old poses and
  // the pair oscillates about the optimum instead of settling. Damped, the rounds reach it.
  double relaxation = 0.7;
  // Without the central's estimate, each round starts with the coarse step of the two-stage
  // distributed solve (graph::coarse_corrections): one rigid move per robot of the group, solved
  // alike by every robot from the group's inter-robot loops and separator poses. The block solves
  // alone leave a bend of the whole map that shrinks by a few percent per round; the coarse step
  // removes it at once. It needs every robot's inter-robot loops and their poses: peers send all
  // their inter-robot separator poses to every robot of their group and relay their loops.
  bool coarse_step = true;
  // A separator pose goes to a peer again only once it has moved this far since it was last sent
  // there (the rounds settle, and most poses stop moving). The topic is reliable, so a peer misses
  // one only when it was out of reach long enough to be unmatched (or restarted): the node then
  // calls resend_separators_to() when the peer's reader matches again. Every `separator_refresh`
  // the peer gets all of them anyway, a safety net.
  double separator_min_change_m = 0.001;
  double separator_min_change_rad = 0.01 * M_PI / 180.0;
  Nanos separator_refresh{std::chrono::seconds(30)};
  // Loops through one keyframe share its cloud's errors: each loop's information is divided by the
  // most loops either of its keyframes takes part in (graph::share_loop_information).
  bool share_loop_information = true;
  // The robot's own loop closures (PCM checks inter-robot loops only) pass through graduated
  // non-convexity in each distributed round's block solve (graph::GncOptions, truncated least
  // squares after the round's bounded least-squares solve; GNC rounds only when an own loop's
  // r^T Omega r exceeds this c^2 there; 0: off). Each round decides afresh: a round's solve is
  // small, and a robot's estimate moves round by round. Inter-robot loops stay quadratic: their far ends are peers'
  // separator poses held fixed, which a group still settling leaves misaligned, and a truncated loss would drop the
  // very loops that align it.
  double own_loop_gnc_threshold = 16.81;
  // Keyframes (and loops) re-sent per step at most, so that a rejoin's backlog (hundreds of
  // keyframes of ~110 KB) goes out over several steps instead of blocking the node's loop under
  // flow control.
  size_t max_resend_per_step = 50;
};

struct OwnKeyframe {
  uint32_t id = 0;
  uint32_t incarnation = 0;  // of the robot's keyframe sequence
  int64_t stamp_ns = 0;      // data time
  Eigen::Isometry3d T_odom = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_prev = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();
};

// What became of a keyframe offered to the core (PeerCore::add_keyframe).
enum class Admission {
  kAccepted,
  kDuplicate,  // this very keyframe is held already (same id, incarnation and stamp): nothing changes
  kRefused,    // it conflicts with what is held: nothing changes, and `reason` says why
};

struct KeyframeAdmission {
  Admission outcome = Admission::kAccepted;
  std::string reason;  // for kRefused: robot, keyframe id, both incarnations
};

struct LoopRecord {
  uint32_t sender = 0, sender_incarnation = 0, seq = 0;
  uint32_t robot_a = 0, keyframe_a = 0, robot_b = 0, keyframe_b = 0;
  bool withdrawn = false;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();
};

struct CentralResult {
  uint32_t central_incarnation = 0;
  uint64_t version = 0;
  Eigen::Isometry3d T_world_robot = Eigen::Isometry3d::Identity();
  KeyframePoses poses;  // own keyframes, T_world_keyframe
  // The central has not placed the robot in its graph yet and returns the robot's own hint (its
  // T_world_robot times the odometry): W is known, but there is no correction in it to relay.
  bool from_hint = false;
};

struct AckIn {
  uint32_t central_incarnation = 0;
  uint32_t robot_incarnation = 0;
  int64_t keyframe = -1;
  int64_t loop_seq = -1;
};

struct Correction {
  Eigen::Isometry3d T_world_robot;  // limited by the fusion thresholds
  double lambda = 1.0;              // the fusion factor applied
  bool from_central = true;
  // Current estimate of own keyframes, in the frame of T_world_robot above (the solution moved with it).
  KeyframePoses poses;
};

struct SeparatorOut {
  uint32_t target = 0;
  // Own keyframes the target's loops touch; with the coarse step, every own keyframe an
  // inter-robot loop touches.
  KeyframePoses poses;
  // Inter-robot loops of this robot that the target is no end of (each relayed once, by the loop's
  // lower robot), for the target's coarse step.
  std::vector<LoopRecord> loops;
  // How many inter-robot loops the sender has (those touching it), and whether its rounds start with
  // the coarse step: a robot runs the coarse step only while every robot of its group does and it
  // holds as many loops touching each of them as that robot says it has.
  uint32_t inter_robot_loops = 0;
  bool coarse_step = false;
};

struct StepOutput {
  std::optional<Transition> transition;
  std::optional<Correction> correction;
  std::vector<SeparatorOut> separators;
  std::optional<Eigen::Isometry3d> world_transform;  // own estimate for the central (on rejoin)
  std::vector<uint32_t> resend_keyframes;
  std::vector<uint32_t> resend_loops;  // own loop seqs
  // Set on the switch to DISTRIBUTED: own keyframes forwarded to the central but not yet delivered
  // (the link was cut before the central's lease lapsed) are to be dropped from the writer, so that
  // they reach the central with the backlog re-sent on rejoining, not as soon as the link returns
  // while the robot still waits out its dwell.
  bool drop_undelivered_keyframes = false;
};

}  // namespace cdc::peer
