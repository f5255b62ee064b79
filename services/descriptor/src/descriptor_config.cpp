#include "descriptor_config.hpp"

#include "cdc/config/reader.hpp"

namespace cdc::descriptor {

DescriptorNodeOptions load_descriptor_options(const std::string& path) {
  DescriptorNodeOptions o;
  config::Reader r(path);
  int robots = static_cast<int>(o.robots);
  r.get<int>(
      "robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.robots = static_cast<uint32_t>(robots);
  r.get<int>(
      "scan_context.rings", o.sc.rings, [](const int& v) { return v >= 1 && v <= 255; }, "1..255");
  r.get<int>(
      "scan_context.sectors", o.sc.sectors, [](const int& v) { return v >= 4 && v <= 255; }, "4..255");
  r.get<double>(
      "scan_context.max_range_m", o.sc.max_range_m, [](const double& v) { return v > 0; }, "> 0");
  r.get<double>(
      "scan_context.sensor_height_m", o.sc.sensor_height_m, [](const double& v) { return v >= 0; }, ">= 0");
  int per_sync = static_cast<int>(o.max_per_sync);
  r.get<int>(
      "max_per_sync", per_sync, [](const int& v) { return v >= 1 && v <= 100000; }, "1..100000");
  o.max_per_sync = static_cast<uint32_t>(per_sync);
  r.get<std::string>("log_level", o.log_level);
  r.finish();
  return o;
}

}  // namespace cdc::descriptor
