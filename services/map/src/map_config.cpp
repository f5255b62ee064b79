#include "map_config.hpp"

#include "cdc/config/reader.hpp"

namespace cdc::map {

MapNodeOptions load_map_options(const std::string& path) {
  MapNodeOptions o;
  config::Reader r(path);
  r.get_count("robots", o.robots, 1, 254);
  r.get_count("central_id", o.central_id, 0, 254);
  r.get_in("cloud_voxel_m", o.core.voxel_m, 0.01, 10.0);
  r.get_in("octree_resolution_m", o.core.octree_resolution_m, 0.01, 10.0);
  r.get_in("max_range_m", o.core.max_range_m, 1.0, 1000.0);
  r.get_in("ray_spacing_m", o.core.ray_spacing_m, 0.0, 1000.0);
  r.get_in("write_period_s", o.write_period_s, 0.0, 86400.0);
  r.get<std::string>("log_level", o.log_level);
  r.finish();
  return o;
}

}  // namespace cdc::map
