// Scan Context descriptors to and from their IDL message (cdc_msg_Descriptor): the quantised cells
// travel DEFLATE-packed (common/dds/compact.hpp). The descriptor service writes descriptors, the
// loop-closure service reads them; both use this one conversion.
#pragma once

#include "cdc/dds/types.hpp"
#include "cdc/lidar/scan_context.hpp"

#include <cstdint>
#include <vector>

namespace cdc::dds_lidar {

// Fills the descriptor fields of `m` (rings, sectors, max_range, quant_scale, packed_cells) from `q`;
// `m.packed_cells` borrows `cells`, which the caller keeps alive until the write.
void descriptor_to_msg(const lidar::QuantizedScanContext& q, float max_range_m, cdc_msg_Descriptor& m,
                       std::vector<uint8_t>& cells);

// The message's descriptor, dequantised. Validate the message first (dds::validate): a message
// whose cells do not unpack to rings x sectors bytes throws std::invalid_argument.
lidar::ScanContext descriptor_from_msg(const cdc_msg_Descriptor& m);

}  // namespace cdc::dds_lidar
