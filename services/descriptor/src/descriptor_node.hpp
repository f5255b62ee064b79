// DDS shell of the descriptor service: the robot's keyframes in (its own domain), their descriptors out
// on the radio (and on the robot's own domain for its loop closure); a peer's sync request answered with
// the range it missed, in the peer's partition. Live descriptors are volatile: whoever missed some asks
// for them, instead of a transient-local history replaying every descriptor to each peer on every
// reconnection. The descriptors are DescriptorCore's.
#pragma once

#include "descriptor_config.hpp"

#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/descriptor/descriptor_core.hpp"
#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <vector>

namespace cdc::descriptor {

struct DescriptorNodeCounters {
  uint64_t descriptors = 0, first_send_bytes = 0;  // first sends (every write, re-sends too: "topics")
  uint64_t sync_requests = 0, resent = 0, resent_bytes = 0;
};

class DescriptorNode {
 public:
  DescriptorNode(const runtime::ServiceOptions& common, const DescriptorNodeOptions& options);
  void spin();
  nlohmann::json stats() const;
  void finish() const;

 private:
  void on_keyframe(const cdc_msg_Keyframe& m);
  void on_sync(const cdc_msg_DescriptorSync& m);
  const cdc_msg_Descriptor& to_msg(const DescriptorRecord& r);

  DescriptorNodeOptions o_;
  runtime::Service service_;
  runtime::Input<cdc_msg_Keyframe> keyframes_;
  runtime::Input<cdc_msg_DescriptorSync> syncs_;
  dds::TopicWriter<cdc_msg_Descriptor> w_desc_;
  std::optional<dds::TopicWriter<cdc_msg_Descriptor>> w_desc_local_;
  dds::PerRobotWriters<cdc_msg_Descriptor> w_resend_;  // to the robot that asked, in its partition

  DescriptorCore core_;
  DescriptorNodeCounters counters_;
  std::vector<Eigen::Vector3f> points_;
  cdc_msg_Descriptor msg_{};  // the message being written; its cells borrow cells_
  std::vector<uint8_t> cells_;
};

}  // namespace cdc::descriptor
