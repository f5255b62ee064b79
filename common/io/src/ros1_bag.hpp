// ROS 1 bag (format 2.0) reader; open_bag() hands .bag files to it.
#pragma once

#include "cdc/io/bag.hpp"

#include <filesystem>
#include <memory>

namespace cdc::io {

// Opens a ROS 1 bag of format 2.0 (chunks uncompressed, bz2 or lz4). Messages come in log-time
// order across all chunks. A bag without index (not closed cleanly) is read by scanning its chunks.
// A damaged bag yields the messages of its intact chunks, then next() throws FormatError naming
// the byte offset of the damage; a damaged version line or bag header record throws here.
std::unique_ptr<BagReader> open_ros1_bag(const std::filesystem::path& path);

}  // namespace cdc::io
