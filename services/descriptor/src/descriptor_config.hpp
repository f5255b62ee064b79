// The descriptor service's configuration (services/descriptor/config/descriptor.yaml).
#pragma once

#include "cdc/lidar/scan_context.hpp"

#include <cstdint>
#include <string>

namespace cdc::descriptor {

struct DescriptorNodeOptions {
  uint32_t robots = 3;
  lidar::ScanContextParams sc;
  uint32_t max_per_sync = 256;  // descriptors sent for one sync request (the requester asks again for more)
  std::string log_level = "info";
};

// Reads a descriptor.yaml (empty path: the defaults); every invalid key is named in the exception.
DescriptorNodeOptions load_descriptor_options(const std::string& path);

}  // namespace cdc::descriptor
