// A rigid transform saved as a 4x4 matrix: 16 numbers, row by row (a reference T_target_source
// for a sweep pair).
#pragma once

#include "cdc/io/error.hpp"

#include <Eigen/Geometry>

#include <filesystem>

namespace cdc::io {

// Throws FormatError naming the file when it holds more or fewer than 16 numbers, or the matrix is
// not rigid (rotation not orthonormal, last row not 0 0 0 1).
Eigen::Isometry3d read_transform_file(const std::filesystem::path& path);

}  // namespace cdc::io
