// Helpers the peer optimiser's core tests share: a test configuration, and records made from the
// synthetic swarm stream (tests/support/swarm_stream.hpp).
#pragma once

#include "cdc/geometry/alignment.hpp"
#include "cdc/peer_optimiser/peer_core.hpp"
#include "swarm_stream.hpp"

#include <Eigen/Geometry>

#include <chrono>
#include <utility>
#include <vector>

namespace cdc::peer {

using namespace std::chrono_literals;

// A pose at (x, y, 0) turned by `yaw` [rad] about z.
inline Eigen::Isometry3d pose_at(double x, double y = 0, double yaw = 0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

inline PeerConfig config(uint32_t robot) {
  PeerConfig c;
  c.robot = robot;
  c.rtdos.range_m = 1e6;
  c.rtdos.dwell = 1s;
  c.rtdos.mask = 500ms;
  c.fusion = {0.1, 0.01};
  c.round_period = 100ms;
  c.resend_grace = 1s;
  c.resend_period = 200ms;
  return c;
}

// Data time of stream keyframe `id` [ns]: one a second.
inline int64_t stamp_of(uint32_t id) { return int64_t{id} * 1'000'000'000; }

inline OwnKeyframe kf_from(const test::StreamKeyframe& k, uint32_t incarnation = 3) {
  return OwnKeyframe{k.id, incarnation, stamp_of(k.id), k.T_odom_keyframe, k.T_prev_keyframe, k.information};
}

inline LoopRecord loop_from(const test::StreamLoop& l) {
  return LoopRecord{l.sender,     3,     l.seq,   l.robot_a,    l.keyframe_a, l.robot_b,
                    l.keyframe_b, false, l.T_a_b, l.information};
}

// The central's result for `robot`: its keyframes 0..upto at `offset` times the truth, with the
// T_world_robot the central fits to them.
inline CentralResult central_for(const test::SwarmStream& s, uint32_t robot, uint32_t upto,
                                 const Eigen::Isometry3d& offset) {
  CentralResult r;
  r.central_incarnation = 11;
  for (uint32_t id = 0; id <= upto; ++id) {
    r.poses.emplace_back(id, offset * s.keyframes[robot][id].T_world_truth);
  }
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> odom_world;  // the central's fitted transform
  for (const auto& [id, T] : r.poses) odom_world.emplace_back(s.keyframes[robot][id].T_odom_keyframe, T);
  r.T_world_robot = geometry::align_poses(odom_world).T_dst_src;
  return r;
}

// Hands each of `cores` (robot r at index r) the loop once per robot it names, as the loop-closure
// service sends it.
inline void add_loop_to_its_robots(std::vector<PeerCore>& cores, const LoopRecord& l) {
  cores[l.robot_a].add_loop(l, Nanos{0});
  if (l.robot_b != l.robot_a) cores[l.robot_b].add_loop(l, Nanos{0});
}

// One distributed round of a swarm at time t: every core steps, then each separator message reaches
// its target. Returns the steps (robot r's at index r).
inline std::vector<StepOutput> exchange_round(std::vector<PeerCore>& cores, Nanos t) {
  std::vector<StepOutput> steps;
  for (PeerCore& c : cores) steps.push_back(c.step(t, false));
  for (uint32_t r = 0; r < steps.size(); ++r) {
    for (const SeparatorOut& s : steps[r].separators) cores[s.target].on_separator(r, s);
  }
  return steps;
}

inline test::SwarmStream three_robot_stream() {
  test::SwarmStreamOptions o;
  o.robots = 3;
  o.keyframes_per_robot = 150;
  return test::make_swarm_stream(o);
}

// Robot 0 alone with its first ten keyframes and a loop from its keyframe 5 to robot 1's 7.
inline void add_robot0_with_a_loop_to_robot1(const test::SwarmStream& s, PeerCore& r0) {
  for (uint32_t id = 0; id < 10; ++id) r0.add_keyframe(kf_from(s.keyframes[0][id]), 0s);
  LoopRecord l = loop_from(s.loops.front());
  l.robot_a = 0;
  l.keyframe_a = 5;
  l.robot_b = 1;
  l.keyframe_b = 7;
  r0.add_loop(l, 0s);
}

}  // namespace cdc::peer
