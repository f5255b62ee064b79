#include "map_config.hpp"

#include "cdc/config/reader.hpp"

namespace cdc::map {

MapNodeOptions load_map_options(const std::string& path) {
  MapNodeOptions o;
  config::Reader r(path);
  auto positive = [](const double& v) { return v > 0; };
  int robots = static_cast<int>(o.robots), central = static_cast<int>(o.central_id);
  r.get<int>(
      "robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  r.get<int>(
      "central_id", central, [](const int& v) { return v >= 0 && v <= 254; }, "0..254");
  r.get<double>("cloud_voxel_m", o.core.voxel_m, positive, "> 0");
  r.get<double>("octree_resolution_m", o.core.octree_resolution_m, positive, "> 0");
  r.get<double>("max_range_m", o.core.max_range_m, positive, "> 0");
  r.get<double>(
      "ray_spacing_m", o.core.ray_spacing_m, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<double>(
      "write_period_s", o.write_period_s, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<std::string>("log_level", o.log_level);
  r.finish();
  o.robots = static_cast<uint32_t>(robots);
  o.central_id = static_cast<uint32_t>(central);
  return o;
}

}  // namespace cdc::map
