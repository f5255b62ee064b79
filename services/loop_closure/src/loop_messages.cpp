#include "loop_messages.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds_lidar/descriptor_convert.hpp"

#include <cmath>
#include <string>

namespace cdc::loops {

KeyframeIn keyframe_in(const cdc_msg_Keyframe& m) {
  KeyframeIn kf;
  kf.robot = m.robot_id;
  kf.id = m.keyframe_id;
  kf.T_prev = dds::to_eigen(m.T_prev_keyframe);
  kf.information = dds::information_to_eigen(m.information);
  kf.T_odom = dds::to_eigen(m.T_odom_keyframe);
  kf.cloud.reserve(m.cloud._length);
  for (uint32_t i = 0; i < m.cloud._length; ++i) {
    kf.cloud.emplace_back(m.cloud._buffer[i].x, m.cloud._buffer[i].y, m.cloud._buffer[i].z);
  }
  return kf;
}

DescriptorIn descriptor_in(const cdc_msg_Descriptor& m) {
  return DescriptorIn{m.robot_id, m.keyframe_id, dds_lidar::descriptor_from_msg(m), dds::to_eigen(m.pose_hint)};
}

dds::Validation check_descriptor_shape(const cdc_msg_Descriptor& m, const lidar::ScanContextParams& sc) {
  if (m.rings == sc.rings && m.sectors == sc.sectors && std::abs(m.max_range - sc.max_range_m) <= 1e-3) {
    return dds::Validation::ok();
  }
  return dds::Validation::fail("rings/sectors/max_range: descriptor of shape " + std::to_string(m.rings) + "x" +
                               std::to_string(m.sectors) + " to " + std::to_string(m.max_range) +
                               " m, this service uses " + std::to_string(sc.rings) + "x" + std::to_string(sc.sectors) +
                               " to " + std::to_string(sc.max_range_m) + " m");
}

std::vector<Eigen::Vector3f> reply_cloud(const cdc_msg_CloudReply& m) {
  std::vector<Eigen::Vector3f> cloud;
  dds::compact::unpack_points(m.packed_points._buffer, m.packed_points._length, m.point_count, m.resolution_m, cloud);
  return cloud;
}

cdc_msg_CloudRequest cloud_request(const CloudWanted& c, uint32_t me, uint32_t incarnation, uint64_t request_id) {
  cdc_msg_CloudRequest q{};
  q.requester_robot_id = me;
  q.request_id = request_id;
  q.requester_incarnation = incarnation;
  q.owner_robot_id = c.robot;
  q.keyframe_id = c.id;
  q.stamp_ns = dds::now_ns();
  return q;
}

cdc_msg_DescriptorSync descriptor_sync(const SyncWanted& w, uint32_t me) {
  cdc_msg_DescriptorSync q{};
  q.requester_robot_id = me;
  q.owner_robot_id = w.robot;
  q.first_keyframe_id = w.first;
  q.last_keyframe_id = w.last;
  q.stamp_ns = dds::now_ns();
  return q;
}

cdc_msg_CloudReply cloud_reply(const cdc_msg_CloudRequest& q, uint32_t me, uint32_t incarnation, bool found,
                               dds::compact::PackedCloud& packed) {
  cdc_msg_CloudReply rep{};
  rep.requester_robot_id = q.requester_robot_id;
  rep.request_id = q.request_id;
  rep.owner_robot_id = me;
  rep.owner_incarnation = incarnation;
  rep.keyframe_id = q.keyframe_id;
  rep.found = found;
  rep.point_count = packed.count;
  rep.resolution_m = packed.resolution_m;
  dds::borrow(rep.packed_points, packed.bytes);
  return rep;
}

cdc_msg_LoopClosure loop_message(const LoopOut& l, uint32_t me, uint32_t incarnation, uint32_t seq) {
  cdc_msg_LoopClosure m{};
  m.robot_a = l.robot_a;
  m.keyframe_a = l.keyframe_a;
  m.robot_b = l.robot_b;
  m.keyframe_b = l.keyframe_b;
  m.sender_robot_id = me;
  m.sender_incarnation = incarnation;
  m.loop_seq = seq;
  m.stamp_ns = dds::now_ns();
  m.status = l.withdrawn ? cdc_msg_LOOP_WITHDRAWN : cdc_msg_LOOP_ACCEPTED;
  m.T_a_b = dds::to_msg(l.T_a_b);
  dds::information_to_msg(l.information, m.information);
  m.fitness = static_cast<float>(l.fitness);
  return m;
}

}  // namespace cdc::loops
