#include "descriptor_config.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/config/scan_context.hpp"

namespace cdc::descriptor {

DescriptorNodeOptions load_descriptor_options(const std::string& path) {
  DescriptorNodeOptions o;
  config::Reader r(path);
  r.get_count("robots", o.robots, 1, 254);
  config::read_scan_context(r, o.sc);
  r.get_in("scan_context.sensor_height_m", o.sc.sensor_height_m, 0.0, 100.0);
  r.get_count("max_per_sync", o.max_per_sync, 1, 100000);
  r.get<std::string>("log_level", o.log_level);
  r.finish();
  return o;
}

}  // namespace cdc::descriptor
