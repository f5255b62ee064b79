// The map service's configuration (services/map/config/map.yaml).
#pragma once

#include "cdc/map/map_core.hpp"

#include <cstdint>
#include <string>

namespace cdc::map {

struct MapNodeOptions {
  uint32_t robots = 3, central_id = 200;
  double write_period_s = 0;  // 0: write on SIGUSR1 and at shutdown only
  MapParams core;
  std::string log_level = "info";
  std::string out_dir = ".";  // where map.pcd and map.bt go (--out)
};

// Reads a map.yaml (empty path: the defaults); every invalid key is named in the exception.
MapNodeOptions load_map_options(const std::string& path);

}  // namespace cdc::map
