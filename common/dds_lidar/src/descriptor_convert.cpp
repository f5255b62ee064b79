#include "cdc/dds_lidar/descriptor_convert.hpp"

#include "cdc/dds/compact.hpp"

#include <stdexcept>
#include <string>

namespace cdc::dds_lidar {

void descriptor_to_msg(const lidar::QuantizedScanContext& q, float max_range_m, cdc_msg_Descriptor& m,
                       std::vector<uint8_t>& cells) {
  m.rings = static_cast<uint16_t>(q.rings);
  m.sectors = static_cast<uint16_t>(q.sectors);
  m.max_range = max_range_m;
  m.quant_scale = q.scale;
  cells = dds::compact::deflate_bytes(q.cells.data(), q.cells.size());
  dds::borrow(m.packed_cells, cells);
}

lidar::ScanContext descriptor_from_msg(const cdc_msg_Descriptor& m) {
  lidar::QuantizedScanContext q;
  q.rings = m.rings;
  q.sectors = m.sectors;
  q.scale = m.quant_scale;
  const std::string err = dds::compact::inflate_bytes(m.packed_cells._buffer, m.packed_cells._length,
                                                      size_t{m.rings} * size_t{m.sectors}, q.cells);
  if (!err.empty()) throw std::invalid_argument("descriptor packed_cells: " + err);
  return lidar::dequantize(q);
}

}  // namespace cdc::dds_lidar
