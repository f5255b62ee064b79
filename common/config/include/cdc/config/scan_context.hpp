// The Scan Context keys of a service's YAML. The descriptor service describes places with them and the
// loop-closure service searches those descriptors with them, so both read the same keys and ranges.
#pragma once

#include "cdc/config/reader.hpp"
#include "cdc/lidar/scan_context.hpp"

namespace cdc::config {

// Reads scan_context.rings, scan_context.sectors and scan_context.max_range_m into p.
void read_scan_context(Reader& r, lidar::ScanContextParams& p);

}  // namespace cdc::config
