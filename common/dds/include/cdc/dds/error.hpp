// One error type for everything the DDS layer can fail at.
#pragma once

#include <dds/dds.h>

#include <stdexcept>
#include <string>
#include <string_view>

namespace cdc::dds {

// A failed Cyclone DDS call (code is the dds_return_t) or a refused configuration.
class DdsError : public std::runtime_error {
 public:
  DdsError(std::string what, dds_return_t code) : std::runtime_error(std::move(what)), code_(code) {}
  dds_return_t code() const noexcept { return code_; }

 private:
  dds_return_t code_;
};

// Returns rc when it is not an error (entities are positive handles), throws DdsError otherwise.
dds_return_t check(dds_return_t rc, std::string_view what);

}  // namespace cdc::dds
