#include "peer_messages.hpp"

#include "cdc/dds/convert.hpp"

namespace cdc::peer {
namespace {

// The poses of a KeyframePose or KeyframePoseF sequence, by keyframe id in message order.
template <class Seq>
KeyframePoses keyframe_poses(const Seq& poses) {
  KeyframePoses out;
  out.reserve(poses._length);
  for (uint32_t i = 0; i < poses._length; ++i) {
    out.emplace_back(poses._buffer[i].keyframe_id, dds::to_eigen(poses._buffer[i].pose));
  }
  return out;
}

// Fills storage with one element per pose, made by element(id, T), and lends it to the message's sequence.
template <class Seq, class Element, class Make>
void lend(Seq& seq, std::vector<Element>& storage, const KeyframePoses& poses, Make element) {
  storage.clear();
  for (const auto& [id, T] : poses) storage.push_back(element(id, T));
  dds::borrow(seq, storage);
}

}  // namespace

cdc_msg_BackendMode to_msg(Mode mode) {
  return mode == Mode::kCentralized ? cdc_msg_MODE_CENTRALIZED : cdc_msg_MODE_DISTRIBUTED;
}

cdc_msg_SwitchReason to_msg(SwitchReason reason) {
  switch (reason) {
    case SwitchReason::kStartup:
      return cdc_msg_REASON_STARTUP;
    case SwitchReason::kLivelinessLost:
      return cdc_msg_REASON_LIVELINESS_LOST;
    case SwitchReason::kOutOfRange:
      return cdc_msg_REASON_OUT_OF_RANGE;
    case SwitchReason::kBackInRange:
      return cdc_msg_REASON_BACK_IN_RANGE;
  }
  return cdc_msg_REASON_STARTUP;
}

Mode from_msg(cdc_msg_BackendMode mode) {
  return mode == cdc_msg_MODE_CENTRALIZED ? Mode::kCentralized : Mode::kDistributed;
}

OwnKeyframe own_keyframe(const cdc_msg_Keyframe& m) {
  return OwnKeyframe{m.keyframe_id,
                     m.incarnation,
                     m.stamp_ns,
                     dds::to_eigen(m.T_odom_keyframe),
                     dds::to_eigen(m.T_prev_keyframe),
                     dds::information_to_eigen(m.information)};
}

LoopRecord loop_record(const cdc_msg_LoopClosure& m) {
  return LoopRecord{m.sender_robot_id,
                    m.sender_incarnation,
                    m.loop_seq,
                    m.robot_a,
                    m.keyframe_a,
                    m.robot_b,
                    m.keyframe_b,
                    m.status == cdc_msg_LOOP_WITHDRAWN,
                    dds::to_eigen(m.T_a_b),
                    dds::information_to_eigen(m.information)};
}

CentralResult central_result(const cdc_msg_OptimizedPoses& m) {
  CentralResult r;
  r.central_incarnation = m.sender_incarnation;
  r.version = m.graph_version;
  r.T_world_robot = dds::to_eigen(m.T_world_robot);
  r.from_hint = m.source == cdc_msg_SOURCE_CENTRAL_HINT;
  r.poses = keyframe_poses(m.poses);
  return r;
}

AckIn ack_in(const cdc_msg_Acknowledgement& m) {
  return AckIn{m.central_incarnation, m.robot_incarnation, m.highest_contiguous_keyframe,
               m.highest_contiguous_loop_seq};
}

SeparatorOut separator_in(const cdc_msg_SeparatorPoses& m) {
  SeparatorOut s;
  s.target = m.target_robot_id;
  s.poses = keyframe_poses(m.poses);
  s.loops.reserve(m.loops._length);
  for (uint32_t i = 0; i < m.loops._length; ++i) s.loops.push_back(loop_record(m.loops._buffer[i]));
  s.inter_robot_loops = m.inter_robot_loops;
  s.coarse_step = m.coarse_step;
  return s;
}

cdc_msg_ModeState mode_state(const Origin& o, Mode mode, SwitchReason reason, std::optional<double> distance,
                             uint32_t transitions) {
  cdc_msg_ModeState m{};
  m.robot_id = o.robot;
  m.incarnation = o.incarnation;
  m.stamp_ns = o.stamp_ns;
  m.mode = to_msg(mode);
  m.reason = to_msg(reason);
  m.distance_to_central = distance.value_or(-1.0);
  m.transition_count = transitions;
  return m;
}

cdc_msg_WorldTransform world_transform(const Origin& o, const Eigen::Isometry3d& T_world_robot, uint64_t rounds) {
  cdc_msg_WorldTransform w{};
  w.robot_id = o.robot;
  w.incarnation = o.incarnation;
  w.stamp_ns = o.stamp_ns;
  w.source = cdc_msg_SOURCE_DISTRIBUTED;
  w.graph_version = rounds;
  w.T_world_robot = dds::to_msg(T_world_robot);
  return w;
}

std::optional<Eigen::Vector3d> status_position(const cdc_msg_RobotStatus& m) {
  if (!m.world_valid) return std::nullopt;
  return dds::to_eigen(m.T_world_base.position);
}

cdc_msg_RobotStatus robot_status(const Origin& o, const std::optional<Eigen::Isometry3d>& T_world_base,
                                 int64_t last_keyframe_id, Mode mode) {
  cdc_msg_RobotStatus s{};
  s.robot_id = o.robot;
  s.incarnation = o.incarnation;
  s.stamp_ns = o.stamp_ns;
  s.world_valid = T_world_base.has_value();
  s.T_world_base = dds::to_msg(T_world_base.value_or(Eigen::Isometry3d::Identity()));
  s.last_keyframe_id = last_keyframe_id;
  s.mode = to_msg(mode);
  s.is_central = false;
  return s;
}

cdc_msg_SeparatorPoses separator_message(const Origin& o, const SeparatorOut& s, uint32_t round,
                                         SeparatorStorage& storage) {
  cdc_msg_SeparatorPoses m{};
  m.robot_id = o.robot;
  m.target_robot_id = s.target;
  m.incarnation = o.incarnation;
  m.round = round;
  m.stamp_ns = o.stamp_ns;
  lend(m.poses, storage.poses, s.poses, [](uint32_t id, const Eigen::Isometry3d& T) {
    return cdc_msg_KeyframePoseF{id, dds::to_msg_f(T)};
  });
  storage.loops.clear();
  for (const LoopRecord& l : s.loops) storage.loops.push_back(loop_message(l));
  dds::borrow(m.loops, storage.loops);
  m.inter_robot_loops = s.inter_robot_loops;
  m.coarse_step = s.coarse_step;
  return m;
}

cdc_msg_LoopClosure loop_message(const LoopRecord& l) {
  cdc_msg_LoopClosure m{};
  m.robot_a = l.robot_a;
  m.keyframe_a = l.keyframe_a;
  m.robot_b = l.robot_b;
  m.keyframe_b = l.keyframe_b;
  m.sender_robot_id = l.sender;
  m.sender_incarnation = l.sender_incarnation;
  m.loop_seq = l.seq;
  m.status = l.withdrawn ? cdc_msg_LOOP_WITHDRAWN : cdc_msg_LOOP_ACCEPTED;
  m.T_a_b = dds::to_msg(l.T_a_b);
  dds::information_to_msg(l.information, m.information);
  return m;
}

cdc_msg_Keyframe keyframe_message(uint32_t robot, const OwnKeyframe& k) {
  cdc_msg_Keyframe m{};
  m.robot_id = robot;
  m.keyframe_id = k.id;
  m.incarnation = k.incarnation;
  m.stamp_ns = k.stamp_ns;
  m.T_odom_keyframe = dds::to_msg(k.T_odom);
  m.T_prev_keyframe = dds::to_msg(k.T_prev);
  dds::information_to_msg(k.information, m.information);
  return m;
}

cdc_msg_KeyframeCloud keyframe_cloud_message(uint32_t robot, const OwnKeyframe& k, dds::compact::PackedCloud& packed) {
  cdc_msg_KeyframeCloud m{};
  m.robot_id = robot;
  m.keyframe_id = k.id;
  m.incarnation = k.incarnation;
  m.stamp_ns = k.stamp_ns;
  m.point_count = packed.count;
  m.resolution_m = packed.resolution_m;
  dds::borrow(m.packed_points, packed.bytes);
  return m;
}

cdc_msg_KeyframeSequence keyframe_sequence(uint32_t robot, const OwnKeyframe* newest) {
  cdc_msg_KeyframeSequence m{};
  m.robot_id = robot;
  m.newest_keyframe_id = newest != nullptr ? int64_t{newest->id} : int64_t{-1};
  m.incarnation = newest != nullptr ? newest->incarnation : 0;
  m.stamp_ns = newest != nullptr ? newest->stamp_ns : 0;
  m.T_odom_keyframe = dds::to_msg(newest != nullptr ? newest->T_odom : Eigen::Isometry3d::Identity());
  return m;
}

cdc_msg_OptimizedPoses correction_message(const Origin& o, const Correction& c, uint64_t version,
                                          std::vector<cdc_msg_KeyframePose>& storage) {
  cdc_msg_OptimizedPoses m{};
  m.robot_id = m.sender_robot_id = o.robot;
  m.sender_incarnation = o.incarnation;
  m.graph_version = version;
  m.stamp_ns = o.stamp_ns;
  m.source = c.from_central ? cdc_msg_SOURCE_CENTRAL : cdc_msg_SOURCE_DISTRIBUTED;
  m.T_world_robot = dds::to_msg(c.T_world_robot);
  lend(m.poses, storage, c.poses, [&o](uint32_t id, const Eigen::Isometry3d& T) {
    return cdc_msg_KeyframePose{o.robot, id, dds::to_msg(T)};
  });
  return m;
}

}  // namespace cdc::peer
