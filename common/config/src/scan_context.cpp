#include "cdc/config/scan_context.hpp"

namespace cdc::config {

void read_scan_context(Reader& r, lidar::ScanContextParams& p) {
  r.get_in("scan_context.rings", p.rings, 1, 255);
  r.get_in("scan_context.sectors", p.sectors, 4, 255);
  r.get_in("scan_context.max_range_m", p.max_range_m, 1.0, 1000.0);
}

}  // namespace cdc::config
