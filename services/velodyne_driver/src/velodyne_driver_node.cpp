#include "velodyne_driver_node.hpp"

#include "udp_receiver.hpp"

#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/io/pcap.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <stdexcept>
#include <thread>

namespace cdc::velodyne_driver {
namespace {

using namespace std::chrono_literals;

// Sleeps until `due`, waking at least every 100 ms; false when shutdown was requested meanwhile.
bool sleep_until(std::chrono::steady_clock::time_point due) {
  while (!dds::ShutdownSignal::requested()) {
    const auto now = std::chrono::steady_clock::now();
    if (now >= due) return true;
    std::this_thread::sleep_for(std::min<std::chrono::steady_clock::duration>(due - now, 100ms));
  }
  return false;
}

}  // namespace

nlohmann::json to_json(const VelodyneNodeStats& s) {
  const DriverStats& c = s.core;
  nlohmann::json j{{"datagrams", c.datagrams},
                   {"packets",
                    {{"ok", c.ok},
                     {"other_port", c.other_port},
                     {"truncated", c.truncated},
                     {"malformed", c.malformed},
                     {"wrong_model", c.wrong_model},
                     {"out_of_order", c.out_of_order}}},
                   {"gaps", c.gaps},
                   {"sweeps", c.sweeps},
                   {"empty_sweeps", c.empty_sweeps},
                   {"stale_sweeps", c.stale_sweeps},
                   {"points", c.points},
                   {"published", s.published},
                   {"kernel_drops", s.kernel_drops},
                   {"receive_buffer_bytes", s.receive_buffer_bytes},
                   {"port", s.port},
                   {"pcap_records", s.pcap_records},
                   {"pcap_skipped", s.pcap_skipped},
                   {"error", s.error}};
  j["topics"] = dds::topic_traffic_json();
  return j;
}

VelodyneDriverNode::VelodyneDriverNode(const runtime::ServiceOptions& common, const VelodyneNodeOptions& options)
    : robot_(common.robot),
      options_(options),
      core_(options.driver),
      participant_(common.radio()),
      // Reliable, as the front-end's reader asks; keep-last 16 so that a slow reader never blocks the driver.
      writer_(participant_, dds::topics::kLidar, dds::qos::sensor_stream(16, true)) {
  if (options_.wait_readers > 0 && !writer_.wait_for_readers(options_.wait_readers, 30s)) {
    throw std::runtime_error("only " + std::to_string(writer_.matched_readers()) + " of " +
                             std::to_string(options_.wait_readers) + " LiDAR readers appeared within 30 s");
  }
}

void VelodyneDriverNode::on_datagram(std::span<const uint8_t> payload, int64_t stamp_ns, uint16_t dst_port) {
  const DatagramStatus status = core_.add_datagram(payload, stamp_ns, dst_port);
  if (status != DatagramStatus::kOk && status != DatagramStatus::kOtherPort) {
    spdlog::debug("datagram of {} bytes skipped: {}", payload.size(), to_string(status));
  }
  while (const std::optional<DriverSweep> s = core_.next_sweep()) publish(*s);
}

void VelodyneDriverNode::publish(const DriverSweep& s) {
  const std::vector<io::CloudPoint>& in = s.sweep.points;
  points_.resize(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    points_[i] = cdc_msg_LidarPoint{in[i].x, in[i].y, in[i].z, in[i].intensity, in[i].time_offset, in[i].ring};
  }
  cdc_msg_LidarScan m{};
  m.robot_id = robot_;
  m.incarnation = options_.incarnation;
  m.seq = s.seq;
  m.stamp_ns = s.stamp_ns;
  m.duration_ns = s.duration_ns;
  m.point_count = static_cast<uint32_t>(points_.size());
  dds::borrow(m.points, points_);
  writer_.write(m);
  ++source_.published;
  spdlog::debug("sweep {}: {} points from {} packets", s.seq, in.size(), s.packets);
}

int VelodyneDriverNode::spin() { return options_.pcap.empty() ? spin_udp() : spin_pcap(); }

int VelodyneDriverNode::spin_udp() {
  UdpReceiver socket(options_.bind_address, options_.driver.port, options_.driver.receive_buffer_bytes);
  source_.port = socket.port();
  source_.receive_buffer_bytes = socket.receive_buffer_bytes();
  spdlog::info("listening on UDP {}:{} (receive buffer {} bytes), publishing sweeps of robot {} on {}",
               options_.bind_address, socket.port(), socket.receive_buffer_bytes(), robot_, dds::topics::kLidar);
  if (socket.receive_buffer_bytes() < options_.driver.receive_buffer_bytes) {
    spdlog::warn(
        "the kernel capped the receive buffer at {} bytes ({} asked for): raise net.core.rmem_max to at least {}",
        socket.receive_buffer_bytes(), options_.driver.receive_buffer_bytes, options_.driver.receive_buffer_bytes);
  }
  std::vector<uint8_t> buffer(65536);  // above any UDP payload: nothing is cut short
  while (!dds::ShutdownSignal::requested()) {
    const std::optional<ReceivedDatagram> d = socket.receive(buffer, 100ms);
    if (!d) continue;
    on_datagram(std::span<const uint8_t>(buffer.data(), d->size), d->stamp_ns, d->port);
    source_.kernel_drops = socket.kernel_drops();
  }
  return 0;
}

int VelodyneDriverNode::spin_pcap() {
  io::PcapReader reader(options_.pcap);
  ReplayPacer pacer(options_.rate);
  spdlog::info("replaying {} (datagrams to port {}, rate {}), publishing sweeps of robot {} on {}", options_.pcap,
               options_.driver.port, options_.rate, robot_, dds::topics::kLidar);
  const auto start = std::chrono::steady_clock::now();
  io::UdpDatagram d;
  int code = 0;
  try {
    while (!dds::ShutdownSignal::requested() && reader.next(d)) {
      const std::optional<std::chrono::nanoseconds> due = pacer.due(d.stamp_ns);
      if (due && !sleep_until(start + *due)) break;
      on_datagram(d.payload, d.stamp_ns, d.dst_port);
    }
  } catch (const io::FormatError& e) {
    source_.error = e.what();  // a damaged capture: what was read before stays published
    spdlog::error("{}", source_.error);
    code = 1;
  }
  core_.end_of_stream();
  const io::PcapStats& p = reader.stats();
  source_.pcap_records = p.records;
  source_.pcap_skipped = p.skipped + p.snapped + p.malformed + p.incomplete_fragments;
  return code;
}

VelodyneNodeStats VelodyneDriverNode::stats() const {
  VelodyneNodeStats s = source_;
  s.core = core_.stats();
  return s;
}

}  // namespace cdc::velodyne_driver
