// Recorded bags read without a ROS installation: ROS 2 (sqlite3 .db3 with metadata.yaml, and MCAP)
// and ROS 1 (.bag v2.0). A reader yields every message of the bag in log-time order with its raw
// serialised bytes; ros_messages.hpp decodes the few message types cdc-slam imports.
#pragma once

#include "cdc/io/error.hpp"

#include <cstdint>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace cdc::io {

enum class Serialization { kCdr, kRos1 };

struct BagTopic {
  std::string name;  // e.g. /velodyne_packets
  std::string type;  // ROS 2 spelling, e.g. sensor_msgs/msg/PointCloud2 (ROS 1 names are mapped to it)
  uint64_t messages = 0;
  // Message encoding as the bag states it ("cdr", "ros1", or another). next() yields the messages of
  // "cdr" and "ros1" topics only; a topic listed here with another encoding (e.g. an MCAP "json"
  // channel) has its messages skipped.
  std::string encoding;
};

struct BagMessage {
  std::string topic;
  std::string type;         // as in BagTopic::type
  int64_t log_time_ns = 0;  // when the recorder received it
  Serialization serialization = Serialization::kCdr;
  std::vector<uint8_t> data;  // the serialised message (CDR with its 4-byte encapsulation header, or ROS 1)
};

class BagReader {
 public:
  virtual ~BagReader() = default;
  virtual std::vector<BagTopic> topics() const = 0;
  // The next message in log-time order; false at the end. Throws FormatError on a damaged bag.
  virtual bool next(BagMessage& out) = 0;
  virtual std::string describe() const = 0;  // format and path, for messages
};

// Opens a ROS 1 .bag, a ROS 2 .db3 or .mcap file, or a ROS 2 bag folder (metadata.yaml beside its
// storage files), judged by content, not only by name. Throws FormatError naming the path.
std::unique_ptr<BagReader> open_bag(const std::filesystem::path& path);

}  // namespace cdc::io
