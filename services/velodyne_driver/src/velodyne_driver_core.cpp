#include "cdc/velodyne_driver/velodyne_driver_core.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>
#include <utility>

namespace cdc::velodyne_driver {
namespace {

io::VelodyneCalibration make_calibration(const VelodyneDriverConfig& c) {
  const std::optional<io::VelodyneModel>& model = c.decoder.model;
  if (!c.calibration.empty()) return io::read_velodyne_calibration(c.calibration, model);
  if (!model)
    throw std::invalid_argument("Velodyne driver: give the sensor's calibration or its model (for the built-in table)");
  return io::default_velodyne_calibration(*model);
}

const io::VelodyneDecoderOptions& decoder_options(const VelodyneDriverConfig& c) {
  const io::VelodyneDecoderOptions& d = c.decoder;
  if (!(d.min_range >= 0.0 && d.min_range < d.max_range)) {
    throw std::invalid_argument("Velodyne driver: need 0 <= min_range_m < max_range_m");
  }
  if (!(d.rpm > 0.0)) throw std::invalid_argument("Velodyne driver: rpm must be positive");
  return d;
}

// Whole turns only, as `cdc-import bag` cuts them.
io::VelodyneSweepOptions sweep_options(const VelodyneDriverConfig& c) {
  if (c.max_gap.count() <= 0) throw std::invalid_argument("Velodyne driver: max_gap must be positive");
  io::VelodyneSweepOptions s = io::VelodyneSweepOptions::whole_turns(c.scan_phase_deg);
  s.max_gap_ns = c.max_gap.count();
  return s;
}

DatagramStatus from_packet_status(io::VelodynePacketStatus s) {
  switch (s) {
    case io::VelodynePacketStatus::kOk:
      return DatagramStatus::kOk;
    case io::VelodynePacketStatus::kTruncated:
      return DatagramStatus::kTruncated;
    case io::VelodynePacketStatus::kMalformed:
      return DatagramStatus::kMalformed;
    case io::VelodynePacketStatus::kWrongModel:
      return DatagramStatus::kWrongModel;
    case io::VelodynePacketStatus::kOutOfOrder:
      return DatagramStatus::kOutOfOrder;
  }
  return DatagramStatus::kMalformed;
}

// Each status with its name and its counter in DriverStats.
struct StatusEntry {
  DatagramStatus status;
  const char* name;
  uint64_t DriverStats::*count;
};
constexpr std::array<StatusEntry, 6> kStatuses{
    {{DatagramStatus::kOk, "ok", &DriverStats::ok},
     {DatagramStatus::kOtherPort, "other_port", &DriverStats::other_port},
     {DatagramStatus::kTruncated, "truncated", &DriverStats::truncated},
     {DatagramStatus::kMalformed, "malformed", &DriverStats::malformed},
     {DatagramStatus::kWrongModel, "wrong_model", &DriverStats::wrong_model},
     {DatagramStatus::kOutOfOrder, "out_of_order", &DriverStats::out_of_order}}};

const StatusEntry* find_status(DatagramStatus status) {
  const auto* it =
      std::find_if(kStatuses.begin(), kStatuses.end(), [&](const StatusEntry& e) { return e.status == status; });
  return it != kStatuses.end() ? it : nullptr;
}

uint64_t& counter(DriverStats& s, DatagramStatus status) {
  const StatusEntry* e = find_status(status);
  return s.*(e != nullptr ? e->count : &DriverStats::malformed);
}

}  // namespace

std::string_view to_string(DatagramStatus status) {
  const StatusEntry* e = find_status(status);
  return e != nullptr ? e->name : "unknown";
}

VelodyneDriverCore::VelodyneDriverCore(const VelodyneDriverConfig& config)
    : config_(config), assembler_(make_calibration(config), decoder_options(config), sweep_options(config)) {}

DatagramStatus VelodyneDriverCore::add_datagram(std::span<const uint8_t> payload, int64_t stamp_ns, uint16_t dst_port) {
  ++stats_.datagrams;
  const DatagramStatus status = dst_port == config_.port ? from_packet_status(assembler_.add_packet(payload, stamp_ns))
                                                         : DatagramStatus::kOtherPort;
  ++counter(stats_, status);
  stats_.gaps = assembler_.stats().gaps;
  return status;
}

std::optional<DriverSweep> VelodyneDriverCore::next_sweep() {
  while (assembler_.has_sweep()) {
    const io::VelodyneSweep v = assembler_.take();
    if (v.points.empty()) {
      ++stats_.empty_sweeps;
      continue;
    }
    DriverSweep out;
    out.sweep = io::to_sweep(v, out.stamp_ns);
    if (last_stamp_ns_ && out.stamp_ns <= *last_stamp_ns_) {
      ++stats_.stale_sweeps;
      continue;
    }
    const auto latest =
        std::max_element(v.points.begin(), v.points.end(),
                         [](const io::VelodynePoint& a, const io::VelodynePoint& b) { return a.time_ns < b.time_ns; });
    out.duration_ns = latest->time_ns - out.stamp_ns;
    out.packets = v.packets;
    out.seq = stats_.sweeps++;
    stats_.points += out.sweep.points.size();
    last_stamp_ns_ = out.stamp_ns;
    return out;
  }
  return std::nullopt;
}

void VelodyneDriverCore::end_of_stream() { assembler_.flush(); }

std::optional<std::chrono::nanoseconds> ReplayPacer::due(int64_t stamp_ns) {
  if (!first_stamp_ns_) first_stamp_ns_ = stamp_ns;
  if (rate_ <= 0.0 || stamp_ns <= *first_stamp_ns_) return std::nullopt;
  return std::chrono::nanoseconds(static_cast<int64_t>(static_cast<double>(stamp_ns - *first_stamp_ns_) / rate_));
}

}  // namespace cdc::velodyne_driver
