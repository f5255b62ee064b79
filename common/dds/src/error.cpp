#include "cdc/dds/error.hpp"

namespace cdc::dds {

dds_return_t check(dds_return_t rc, std::string_view what) {
  if (rc < 0) {
    throw DdsError(std::string(what) + " failed: " + dds_strretcode(rc) + " (" + std::to_string(rc) + ")", rc);
  }
  return rc;
}

}  // namespace cdc::dds
