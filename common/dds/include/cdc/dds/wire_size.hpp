// Serialised (XCDR1) payload size of the messages whose traffic the services account for: the
// bytes a sample puts on the wire before RTPS headers. Used for per-topic and per-peer byte
// counters; exact for the fixed fields, with the sequences' length prefixes and alignment padding.
#pragma once

#include "cdc/dds/types.hpp"

#include <cstddef>

namespace cdc::dds {

namespace wire {
constexpr size_t kEncapsulation = 4;
constexpr size_t kPose = 7 * 8;
constexpr size_t kInformation = 36 * 8;
inline size_t align(size_t n, size_t a) { return (n + a - 1) / a * a; }
}  // namespace wire

inline size_t wire_size(const cdc_msg_Descriptor& m) {
  // robot, keyframe, incarnation (12) | stamp (8) | rings, sectors (4) | max_range, quant_scale (8)
  size_t n = 32;
  n += 4 + 4 * static_cast<size_t>(m.ring_key._length);
  n += 4 + m.packed_cells._length;
  n = wire::align(n, 8) + wire::kPose;
  return wire::kEncapsulation + n;
}

inline size_t wire_size(const cdc_msg_CloudRequest& m) {
  (void)m;
  return wire::kEncapsulation + 4 + 4 + 8 + 4 + 4 + 4 + 8;  // with padding before the 64-bit fields
}

inline size_t wire_size(const cdc_msg_DescriptorSync& m) {
  (void)m;
  return wire::kEncapsulation + 4 * 4 + 8;  // ids and range, stamp
}

inline size_t wire_size(const cdc_msg_CloudReply& m) {
  // ids (4 + 4, pad, 8), owner, incarnation, keyframe (12), found (1, pad 3), point_count, resolution (8)
  return wire::kEncapsulation + 4 + 4 + 8 + 4 + 4 + 4 + 1 + 3 + 4 + 4 + 4 + m.packed_points._length;
}

inline size_t wire_size(const cdc_msg_LoopClosure& m) {
  (void)m;
  // 7 x 32-bit ids and counters, stamp, status, pose, information, fitness (with padding)
  return wire::kEncapsulation + 28 + 4 + 8 + 4 + 4 + wire::kPose + wire::kInformation + 4;
}

}  // namespace cdc::dds
