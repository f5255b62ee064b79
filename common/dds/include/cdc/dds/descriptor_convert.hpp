// Scan Context descriptors to and from their IDL message (cdc_msg_Descriptor): the quantised cells
// travel DEFLATE-packed (compact.hpp). Header-only: it needs only the descriptor structs of
// common/lidar, so users link cdc_lidar themselves.
#pragma once

#include "cdc/dds/compact.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/lidar/scan_context.hpp"

#include <stdexcept>
#include <vector>

namespace cdc::dds {

// Fills the descriptor fields of `m` from `q`, borrowing the caller-owned storage for the packed
// cell bytes (kept alive until the write).
inline void descriptor_to_msg(const lidar::QuantizedScanContext& q, float max_range_m, cdc_msg_Descriptor& m,
                              std::vector<uint8_t>& cells) {
  m.rings = static_cast<uint16_t>(q.rings);
  m.sectors = static_cast<uint16_t>(q.sectors);
  m.max_range = max_range_m;
  m.quant_scale = q.scale;
  cells = compact::deflate_bytes(q.cells.data(), q.cells.size());
  borrow(m.packed_cells, cells);
}

// The message's descriptor, dequantised (validate the message first: a message that does not
// unpack throws std::invalid_argument).
inline lidar::ScanContext descriptor_from_msg(const cdc_msg_Descriptor& m) {
  lidar::QuantizedScanContext q;
  q.rings = m.rings;
  q.sectors = m.sectors;
  q.scale = m.quant_scale;
  const std::string err = compact::inflate_bytes(m.packed_cells._buffer, m.packed_cells._length,
                                                 size_t{m.rings} * size_t{m.sectors}, q.cells);
  if (!err.empty()) throw std::invalid_argument("descriptor packed_cells: " + err);
  return lidar::dequantize(q);
}

}  // namespace cdc::dds
