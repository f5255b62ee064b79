// The loop-closure service's messages and the core's types, one into the other: keyframes and
// descriptors in, cloud requests and replies between owners, descriptor resend requests and loop
// closures out.
#pragma once

#include "cdc/dds/compact.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/lidar/scan_context.hpp"
#include "cdc/loop_closure/descriptor_sequencer.hpp"
#include "cdc/loop_closure/loop_core.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace cdc::loops {

KeyframeIn keyframe_in(const cdc_msg_Keyframe& m);
DescriptorIn descriptor_in(const cdc_msg_Descriptor& m);

// A descriptor of another shape than this service's Scan Context (rings, sectors, range) cannot be
// compared with its own: refused, naming both shapes.
dds::Validation check_descriptor_shape(const cdc_msg_Descriptor& m, const lidar::ScanContextParams& sc);

// The cloud of a reply that passed dds::validate.
std::vector<Eigen::Vector3f> reply_cloud(const cdc_msg_CloudReply& m);

// Stamped now.
cdc_msg_CloudRequest cloud_request(const CloudWanted& c, uint32_t me, uint32_t incarnation, uint64_t request_id);
cdc_msg_DescriptorSync descriptor_sync(const SyncWanted& w, uint32_t me);
// The reply of owner `me` to request q: the keyframe's cloud (found), or word that it has none. The
// reply borrows `packed`'s bytes, which must outlive it.
cdc_msg_CloudReply cloud_reply(const cdc_msg_CloudRequest& q, uint32_t me, uint32_t incarnation, bool found,
                               dds::compact::PackedCloud& packed);
// Loop l as robot `me` writes it under sequence number seq, stamped now.
cdc_msg_LoopClosure loop_message(const LoopOut& l, uint32_t me, uint32_t incarnation, uint32_t seq);

}  // namespace cdc::loops
