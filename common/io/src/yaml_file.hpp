// A YAML file read whole for the io readers; a file that cannot be read or parsed is a FormatError
// that names it.
#pragma once

#include "cdc/io/error.hpp"

#include <yaml-cpp/yaml.h>

#include <string>

namespace cdc::io::detail {

inline YAML::Node load_yaml_file(const std::string& file) {
  try {
    return YAML::LoadFile(file);
  } catch (const YAML::Exception& e) {
    throw FormatError(file + ": not readable or not valid YAML: " + e.what());
  }
}

}  // namespace cdc::io::detail
