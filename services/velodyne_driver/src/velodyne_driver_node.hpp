// DDS glue of the Velodyne driver: datagrams from a UDP socket (or replayed from a pcap capture) handed to
// VelodyneDriverCore, the sweeps it yields published as LidarScan on cdc/sensor/lidar.
#pragma once

#include "cdc/velodyne_driver/velodyne_driver_core.hpp"

#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/runtime/options.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace cdc::velodyne_driver {

// The robot and its domain are the shared options' (runtime::ServiceOptions).
struct VelodyneNodeOptions {
  uint32_t incarnation = 0;  // drawn at start-up: tells receivers a restarted driver from the old one
  std::string bind_address = "0.0.0.0";
  std::string pcap;           // non-empty: replay this capture instead of listening
  double rate = 1.0;          // replay speed: 1 the capture's own, 2 twice as fast, 0 as fast as possible
  uint32_t wait_readers = 0;  // wait (up to 30 s) for this many LidarScan readers before the first datagram
  VelodyneDriverConfig driver;
};

struct VelodyneNodeStats {
  DriverStats core;
  uint64_t published = 0;        // LidarScan samples written
  uint64_t kernel_drops = 0;     // datagrams the socket dropped (its buffer was full)
  int receive_buffer_bytes = 0;  // as the kernel granted it (UDP)
  uint16_t port = 0;             // the UDP port listened on (UDP)
  uint64_t pcap_records = 0;     // capture records read (replay)
  uint64_t pcap_skipped = 0;     // records that were not UDP/IPv4, or damaged (replay)
  std::string error;             // why the source stopped early, empty when it did not
};
nlohmann::json to_json(const VelodyneNodeStats& s);

class VelodyneDriverNode {
 public:
  VelodyneDriverNode(const runtime::ServiceOptions& common, const VelodyneNodeOptions& options);

  // One datagram: to the core, then every sweep it completes out on cdc/sensor/lidar.
  void on_datagram(std::span<const uint8_t> payload, int64_t stamp_ns, uint16_t dst_port);

  // Listens (or replays the capture to its end) until shutdown is requested. Returns the exit code:
  // 0, or 1 when the source failed (a damaged capture: stats().error says where).
  int spin();

  VelodyneNodeStats stats() const;

 private:
  int spin_udp();
  int spin_pcap();
  void publish(const DriverSweep& s);

  uint32_t robot_;
  VelodyneNodeOptions options_;
  VelodyneDriverCore core_;
  dds::Participant participant_;
  dds::TopicWriter<cdc_msg_LidarScan> writer_;
  std::vector<cdc_msg_LidarPoint> points_;  // the message's point storage, reused
  VelodyneNodeStats source_;                // publishing and source counters (the core's are added by stats())
};

}  // namespace cdc::velodyne_driver
