// The real VLP-16 packets of the nebula fixture (CDC_DATA_DIR/real/packets/velodyne, ../shared/data
// without it): where the bag and its calibration are, and each packet of the bag.
#pragma once

#include "cdc/io/bag.hpp"
#include "cdc/io/ros_messages.hpp"

#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <vector>

namespace cdc::test {

struct VelodynePacket {
  std::vector<uint8_t> data;
  int64_t stamp_ns = 0;
};

inline std::filesystem::path velodyne_fixture_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  const std::filesystem::path data = env != nullptr ? std::filesystem::path(env) : "../shared/data";
  return data / "real" / "packets" / "velodyne";
}

inline std::filesystem::path vlp16_bag() { return velodyne_fixture_dir() / "vlp16" / "1673400471837873222"; }

inline std::filesystem::path vlp16_calibration() { return velodyne_fixture_dir() / "calibration" / "VLP16.yaml"; }

// Every packet of the VLP-16 bag, in bag order; empty when the bag is absent.
inline std::vector<VelodynePacket> vlp16_packets() {
  std::vector<VelodynePacket> out;
  if (!std::filesystem::exists(vlp16_bag())) return out;
  auto reader = io::open_bag(vlp16_bag());
  io::BagMessage m;
  while (reader->next(m)) {
    if (m.type != "velodyne_msgs/msg/VelodyneScan") continue;
    for (const io::VelodynePacketMsg& p : io::decode_velodyne_scan(m).packets)
      out.push_back({{p.data.begin(), p.data.end()}, p.stamp_ns});
  }
  return out;
}

}  // namespace cdc::test
