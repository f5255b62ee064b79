#include "descriptor_node.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds_lidar/descriptor_convert.hpp"
#include "cdc/runtime/stats.hpp"

#include <spdlog/spdlog.h>

namespace cdc::descriptor {

NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(DescriptorNodeCounters, descriptors, first_send_bytes, sync_requests, resent,
                                   resent_bytes)

namespace {

namespace topics = dds::topics;

}  // namespace

DescriptorNode::DescriptorNode(const runtime::ServiceOptions& common, const DescriptorNodeOptions& o)
    : o_(o),
      service_(runtime::Domains::kRobot, common, runtime::swarm_limits(o.robots)),
      keyframes_(service_, service_.secondary(), topics::kKeyframe,
                 dds::qos::event_stream(4096).partitions(dds::partitions::own_reader(common.robot))),
      syncs_(service_, service_.radio(), topics::kDescriptorSync, dds::qos::event_stream(256)),
      w_desc_(service_.radio(), topics::kDescriptor, dds::qos::event_stream(256)),
      w_resend_(service_.radio(), w_desc_.topic(), dds::qos::event_stream(static_cast<int32_t>(o.max_per_sync)),
                o.robots),
      core_(o.sc, o.max_per_sync) {
  // On a local domain of its own the robot's loop closure gets its descriptors there too, also while
  // the radio is cut.
  if (service_.split()) {
    w_desc_local_.emplace(service_.secondary(), topics::kDescriptor, dds::qos::event_stream(256));
  }
  const uint32_t me = common.robot;
  keyframes_.filter([me](const cdc_msg_Keyframe& m) { return m.robot_id == me; }).on([this](const cdc_msg_Keyframe& m) {
    on_keyframe(m);
  });
  syncs_.filter([me](const cdc_msg_DescriptorSync& m) { return m.owner_robot_id == me; })
      .on([this](const cdc_msg_DescriptorSync& m) { on_sync(m); });
  spdlog::info(
      "descriptor service of robot {} up: Scan Context {}x{} to {} m, domain {}{}", me, o.sc.rings, o.sc.sectors,
      o.sc.max_range_m, common.domain_id(),
      service_.split() ? ", own keyframes on local domain " + std::to_string(common.local_domain) : std::string());
}

void DescriptorNode::spin() {
  while (service_.wait(std::chrono::milliseconds(200))) {
    syncs_.poll(64);
    keyframes_.poll(64);
  }
}

void DescriptorNode::on_keyframe(const cdc_msg_Keyframe& m) {
  KeyframeCloud k;
  k.robot = m.robot_id;
  k.incarnation = m.incarnation;
  k.keyframe_id = m.keyframe_id;
  k.stamp_ns = m.stamp_ns;
  k.T_odom_keyframe = dds::to_eigen(m.T_odom_keyframe);
  points_.clear();
  for (uint32_t i = 0; i < m.cloud._length; ++i) {
    points_.emplace_back(m.cloud._buffer[i].x, m.cloud._buffer[i].y, m.cloud._buffer[i].z);
  }
  k.points.swap(points_);
  const DescriptorRecord* r = core_.describe(k);
  points_.swap(k.points);
  if (r == nullptr) return;  // described before: peers that missed it ask for it
  const cdc_msg_Descriptor& d = to_msg(*r);
  w_desc_.write(d);
  if (w_desc_local_) w_desc_local_->write(d);
  ++counters_.descriptors;
  counters_.first_send_bytes += dds::serialized_size(d);
}

void DescriptorNode::on_sync(const cdc_msg_DescriptorSync& m) {
  ++counters_.sync_requests;
  dds::Writer<cdc_msg_Descriptor>* to = w_resend_.to(m.requester_robot_id);
  if (to == nullptr) return;  // validated: a robot of the swarm
  const auto records = core_.resend(m.first_keyframe_id, m.last_keyframe_id);
  for (const DescriptorRecord* r : records) {
    const cdc_msg_Descriptor& d = to_msg(*r);
    to->write(d);
    ++counters_.resent;
    counters_.resent_bytes += dds::serialized_size(d);
  }
  spdlog::debug("robot {} asked for descriptors {}..{}: {} sent", m.requester_robot_id, m.first_keyframe_id,
                m.last_keyframe_id, records.size());
}

const cdc_msg_Descriptor& DescriptorNode::to_msg(const DescriptorRecord& r) {
  msg_ = cdc_msg_Descriptor{};
  msg_.robot_id = r.robot;
  msg_.keyframe_id = r.keyframe_id;
  msg_.incarnation = r.incarnation;
  msg_.stamp_ns = r.stamp_ns;
  msg_.pose_hint = dds::to_msg_f(r.pose_hint);
  dds_lidar::descriptor_to_msg(r.descriptor, static_cast<float>(o_.sc.max_range_m), msg_, cells_);
  return msg_;
}

nlohmann::json DescriptorNode::stats() const {
  nlohmann::json j = counters_;
  const auto& c = counters_;
  j["robot"] = service_.options().robot;
  j["repeated_keyframes"] = core_.counters().repeated;
  j["bytes_per_descriptor"] =
      c.descriptors > 0 ? static_cast<double>(c.first_send_bytes) / static_cast<double>(c.descriptors) : 0.0;
  j["radio_cuts"] = service_.robot_domains()->radio_cuts();
  return j;
}

void DescriptorNode::finish() const {
  runtime::write_stats(service_, stats());
  spdlog::info("stopped after {} descriptors ({} bytes)", counters_.descriptors, counters_.first_send_bytes);
}

}  // namespace cdc::descriptor
