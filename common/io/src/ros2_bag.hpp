// Internal pieces of the ROS 2 bag readers that open_bag() (bag.cpp) assembles: one storage file
// (sqlite3 or MCAP, on disk or decompressed in memory) per reader, and a reader merging several in
// log-time order (split bags).
#pragma once

#include "cdc/io/bag.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace cdc::io::detail {

enum class MessageCompression { kNone, kZstd };  // rosbag2 compression_mode MESSAGE

// A rosbag2 sqlite3 storage file. Messages come ordered by timestamp (then row id).
std::unique_ptr<BagReader> open_sqlite_bag(const std::filesystem::path& path,
                                           MessageCompression compression = MessageCompression::kNone);
// The same from the bytes of a database held in memory (a .db3.zstd file decompressed); `name`
// names it in messages.
std::unique_ptr<BagReader> open_sqlite_bag_bytes(std::vector<uint8_t> bytes, const std::string& name,
                                                 MessageCompression compression = MessageCompression::kNone);

// An MCAP file, mapped into memory, or MCAP bytes held in memory.
std::unique_ptr<BagReader> open_mcap_bag(const std::filesystem::path& path);
std::unique_ptr<BagReader> open_mcap_bag_bytes(std::vector<uint8_t> bytes, const std::string& name);

// Yields the messages of all parts in log-time order (ties: the earlier part first); topics() sums the
// parts' counts per topic and type.
std::unique_ptr<BagReader> merge_bags(std::vector<std::unique_ptr<BagReader>> parts, std::string description);

// The ROS 2 spelling of a message type: "pkg/Type" -> "pkg/msg/Type"; other names unchanged.
std::string ros2_type_name(std::string_view type);

}  // namespace cdc::io::detail
