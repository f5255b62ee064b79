// Converts the simulated swarm stream into the central optimiser core's inputs (tests, benchmarks).
#pragma once

#include "cdc/central_optimiser/central_core.hpp"
#include "swarm_stream.hpp"

namespace cdc::test {

inline central::KeyframeIn to_central(const StreamKeyframe& k, uint32_t incarnation = 7) {
  central::KeyframeIn in;
  in.robot = k.robot;
  in.incarnation = incarnation;
  in.id = k.id;
  in.stamp_ns = int64_t{k.id} * 1'000'000'000;  // one a second
  in.T_odom_keyframe = k.T_odom_keyframe;
  in.T_prev_keyframe = k.T_prev_keyframe;
  in.information = k.information;
  return in;
}

inline central::LoopIn to_central(const StreamLoop& l, uint32_t incarnation = 7) {
  central::LoopIn in;
  in.sender = l.sender;
  in.sender_incarnation = incarnation;
  in.seq = l.seq;
  in.robot_a = l.robot_a;
  in.keyframe_a = l.keyframe_a;
  in.robot_b = l.robot_b;
  in.keyframe_b = l.keyframe_b;
  in.T_a_b = l.T_a_b;
  in.information = l.information;
  return in;
}

}  // namespace cdc::test
