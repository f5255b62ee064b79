// The Velodyne driver's core: UDP datagrams (payload and arrival stamp) in, sweeps ready to publish out.
// Pure: no DDS, no sockets, no threads. The node feeds it whatever the socket or a pcap replay hands over
// and publishes what it yields; every decision about a datagram or a sweep is taken here.
//
// Sweeps follow the rule of `cdc-import bag` (sim/tools/import.cpp), so both make the same sweeps of the
// same packets: the assembler cuts at scan_phase_deg, the first sweep of the stream (which starts wherever
// the stream starts) and sweeps ended early by a silence longer than max_gap or by the end of the stream
// are not emitted, and a sweep without points in range or whose stamp is not after the previous sweep's is
// dropped (counted).
#pragma once

#include "cdc/io/cloud.hpp"
#include "cdc/io/velodyne.hpp"

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>

namespace cdc::velodyne_driver {

// The decoder's defaults for a VLP-16, the driver's sensor unless the configuration names another.
inline io::VelodyneDecoderOptions vlp16_decoder_options() {
  io::VelodyneDecoderOptions d;
  d.model = io::VelodyneModel::kVLP16;
  return d;
}

struct VelodyneDriverConfig {
  // The model (nullopt: from each packet's product id), the return mode, the nominal speed and the range
  // and azimuth filters, as the decoder takes them.
  io::VelodyneDecoderOptions decoder = vlp16_decoder_options();
  std::filesystem::path calibration;  // calibration YAML (ROS driver format); empty: built-in table
  double scan_phase_deg = 0.0;        // [deg] azimuth where sweeps are cut, [0, 360]
  std::chrono::nanoseconds max_gap{std::chrono::milliseconds(50)};  // a longer silence ends a sweep (dropped)
  uint16_t port = 2368;                                             // UDP destination port of the data packets
  int receive_buffer_bytes = 8 << 20;  // SO_RCVBUF asked for (Linux grants twice that, capped at
                                       // 2 x net.core.rmem_max)
  std::string log_level = "info";
};

// Reads a velodyne.yaml (empty path: the defaults). A relative calibration path is taken from the YAML
// file's folder. Throws config::ConfigError listing every invalid or unknown key.
VelodyneDriverConfig load_driver_config(const std::string& path);

// "auto" (nullopt) or a model name velodyne_model_from_string accepts; throws std::invalid_argument.
std::optional<io::VelodyneModel> parse_model(std::string_view name);
// "auto" (nullopt), "strongest", "last" or "dual"; throws std::invalid_argument.
std::optional<io::VelodyneReturnMode> parse_return_mode(std::string_view name);

// What became of one datagram.
enum class DatagramStatus {
  kOk,          // decoded into the sweep in progress
  kOtherPort,   // addressed to another port than the data port (position packets, other traffic)
  kTruncated,   // shorter than a data packet (1206 bytes)
  kMalformed,   // longer than a data packet, or a bad block id / azimuth / return mode
  kWrongModel,  // the packet's product id names another model than the configured one
  kOutOfOrder,  // its stamp or its azimuth goes back within the sweep
};
std::string_view to_string(DatagramStatus status);

struct DriverStats {
  uint64_t datagrams = 0;  // offered
  uint64_t ok = 0;         // by status (DatagramStatus)
  uint64_t other_port = 0;
  uint64_t truncated = 0;
  uint64_t malformed = 0;
  uint64_t wrong_model = 0;
  uint64_t out_of_order = 0;
  uint64_t gaps = 0;          // silences longer than max_gap (each ends the sweep in progress, which is dropped)
  uint64_t sweeps = 0;        // yielded to publish
  uint64_t empty_sweeps = 0;  // dropped: no point in range
  uint64_t stale_sweeps = 0;  // dropped: stamp not after the previous sweep's
  uint64_t points = 0;        // in the sweeps yielded
};

// A sweep ready to publish as a cdc/sensor/lidar LidarScan.
struct DriverSweep {
  uint64_t seq = 0;         // 0, 1, 2, ... in the order sweeps are yielded
  int64_t stamp_ns = 0;     // time of the earliest point [ns]
  int64_t duration_ns = 0;  // latest point's time - earliest's [ns]: every time_offset lies in [0, duration]
  uint32_t packets = 0;     // packets that contributed
  io::Sweep sweep;          // sensor frame (x forward, y left, z up), time offsets [s] from stamp_ns, rings,
                            // intensity 0..1
};

class VelodyneDriverCore {
 public:
  // Reads the calibration (config.calibration, else the built-in table of config.model). Throws
  // io::FormatError naming a bad calibration file, std::invalid_argument for a configuration that
  // names neither a calibration nor a model, or an out-of-range setting.
  explicit VelodyneDriverCore(const VelodyneDriverConfig& config);

  // Feeds one datagram: its UDP payload, its stamp [ns since the epoch] (arrival or capture time) and
  // the port it was addressed to. Never throws on the datagram's content: bad ones are counted.
  DatagramStatus add_datagram(std::span<const uint8_t> payload, int64_t stamp_ns, uint16_t dst_port);

  // The next sweep ready to publish, nullopt when none is.
  std::optional<DriverSweep> next_sweep();

  // The stream ended (end of a capture): the sweep in progress is incomplete and dropped, and the next
  // datagram starts afresh.
  void end_of_stream();

  const DriverStats& stats() const { return stats_; }
  const io::VelodyneCalibration& calibration() const { return assembler_.decoder().calibration(); }
  // The model of the last packet decoded (or the configured one).
  std::optional<io::VelodyneModel> model() const { return assembler_.decoder().model(); }

 private:
  VelodyneDriverConfig config_;
  io::VelodyneSweepAssembler assembler_;
  DriverStats stats_;
  std::optional<int64_t> last_stamp_ns_;  // of the last sweep yielded
};

// Paces a replay: a datagram captured at `stamp_ns` is due (capture time - first capture time) / rate
// after the replay started; rate <= 0 replays as fast as possible. Captures whose clock steps back are
// due at once.
class ReplayPacer {
 public:
  explicit ReplayPacer(double rate) : rate_(rate) {}
  // How long after the replay's start the datagram is due; nullopt: at once.
  std::optional<std::chrono::nanoseconds> due(int64_t stamp_ns);

 private:
  double rate_;
  std::optional<int64_t> first_stamp_ns_;
};

}  // namespace cdc::velodyne_driver
