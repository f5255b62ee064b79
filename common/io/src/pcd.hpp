// PCD files (ascii, binary and binary_compressed) read by the io library's own parser into a
// PointCloud2 layout, so that cloud_points decodes their fields like any other cloud. PCL's PCD reader
// trusts its input (a malformed header or data terminates the process), so it never sees a file here.
#pragma once

#include "cdc/io/ros_messages.hpp"

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace cdc::io::detail {

// The whole file as a cloud: one row of POINTS points, fields at the offsets SIZE x COUNT gives them,
// data little-endian. Fields of a type a PointCloud2 has no code for (8-byte integers) keep their bytes
// with datatype 0, so only a cloud that needs one of them is refused. Throws FormatError naming the
// file and the line (header, ascii data) or byte offset (binary data) of what is wrong.
PointCloud2Msg read_pcd(const std::filesystem::path& path);

// LZF (liblzf's format, which PCL's binary_compressed data uses), decoded to exactly `expected`
// bytes. `where` prefixes errors; byte offsets in them count from `base`.
std::vector<uint8_t> lzf_decode(std::span<const uint8_t> in, uint64_t expected, const std::string& where,
                                uint64_t base);

}  // namespace cdc::io::detail
