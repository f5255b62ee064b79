// Velodyne packet decoding: the 1206-byte UDP data packets of the VLP-16, VLP-32C, HDL-32E, HDL-64E
// (S2/S3) and VLS-128, the sensor's calibration (YAML, or built-in tables from the user manuals), points
// with their firing time and ring, and a sweep assembler that a UDP receive loop or a bag reader feeds
// packet by packet.
//
// Frame: x forward, y left, z up (the frame of the ROS drivers and of nebula's reference clouds). The
// sensor's own azimuth runs clockwise seen from above, 0 on the x axis, so a point at azimuth a and
// elevation e lies at (d cos e cos a, -d cos e sin a, d sin e) before the per-laser offsets.
//
// Packet layout (all models): 12 data blocks of 100 bytes {uint16 block id, uint16 azimuth [0.01 deg],
// 32 x {uint16 distance, uint8 intensity}}, then uint32 GPS time [us past the hour] at byte 1200 and
// two factory bytes: return mode (1204: 0x37 strongest, 0x38 last, 0x39 dual) and product id (1205).
#pragma once

#include "cdc/io/cloud.hpp"
#include "cdc/io/error.hpp"

#include <cstdint>
#include <deque>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace cdc::io {

inline constexpr std::size_t kVelodynePacketSize = 1206;

// kHDL64E is the HDL-64E S2 and S2.1 (KITTI's sensor), kHDL64ES3 the S3. Their packets look alike and
// carry no product id; their firing timing differs, so the configured model tells them apart.
enum class VelodyneModel { kVLP16, kVLP32C, kHDL32E, kHDL64E, kHDL64ES3, kVLS128 };

// "VLP16", "VLP32C", "HDL32E", "HDL64E", "HDL64E_S3", "VLS128".
std::string_view to_string(VelodyneModel model);
// Accepts the names above, case-insensitive, with or without '-' or '_' ("VLP-16", "vlp32" for the
// VLP-32C, "HDL-64E-S2" and "HDL-64E-S2.1" for the HDL64E, "HDL-64E-S3", ...); throws
// std::invalid_argument naming the text otherwise.
VelodyneModel velodyne_model_from_string(std::string_view name);
// The model a packet's product-id byte (1205) names: 0x21 HDL-32E, 0x22 VLP-16, 0x24 VLP-16 Hi-Res,
// 0x28 VLP-32C, 0xA1 VLS-128. The HDL-64E has no product id (it uses those bytes for its status).
std::optional<VelodyneModel> velodyne_model_from_product_id(uint8_t product_id);
int velodyne_laser_count(VelodyneModel model);

// ---------------------------------------------------------------------------------------------
// Calibration

struct VelodyneLaserCalibration {
  int laser_id = 0;                      // the laser's index in the packet's firing order
  double rot_correction = 0.0;           // [rad] subtracted from the sensor's azimuth
  double vert_correction = 0.0;          // [rad] elevation, up positive
  double dist_correction = 0.0;          // [m] added to the measured distance
  bool two_pt_correction = false;        // apply dist_correction_x/y (HDL-64E two-point model)
  double dist_correction_x = 0.0;        // [m]
  double dist_correction_y = 0.0;        // [m]
  double vert_offset_correction = 0.0;   // [m] height of the laser's origin
  double horiz_offset_correction = 0.0;  // [m] sideways offset of the laser's origin
  double focal_distance = 0.0;           // [cm] HDL-64E intensity model
  double focal_slope = 0.0;
  double min_intensity = 0.0, max_intensity = 255.0;
  int ring = 0;  // 0 = lowest elevation, counting upwards
};

struct VelodyneCalibration {
  std::string source;                            // file path or "built-in <model>"
  double distance_resolution = 0.0;              // [m] as the file states it (informative; see decoder)
  std::vector<VelodyneLaserCalibration> lasers;  // indexed by laser_id, 0..n-1
};

// Reads the YAML calibration format of the ROS Velodyne drivers: num_lasers, distance_resolution and
// lasers: [{laser_id, rot_correction, vert_correction, dist_correction, [dist_correction_x/y,
// two_pt_correction_available, vert_offset_correction, horiz_offset_correction, focal_distance,
// focal_slope, min_intensity, max_intensity]}]. Missing required keys, a bad value, duplicate or
// missing laser ids, or a laser count that differs from num_lasers or from `model` throw FormatError
// naming the file and the entry.
VelodyneCalibration read_velodyne_calibration(const std::filesystem::path& path,
                                              std::optional<VelodyneModel> model = std::nullopt);
// Built-in nominal tables from the user manuals (elevation and azimuth offset per laser). The HDL-64E
// is calibrated unit by unit: its table is the nominal one (upper block +2 to -8.33 deg in 1/3 deg
// steps, lower block -8.83 to -24.33 deg in 1/2 deg steps, laser ids in elevation order) and a real
// unit needs its own file.
VelodyneCalibration default_velodyne_calibration(VelodyneModel model);

// ---------------------------------------------------------------------------------------------
// Packets and points

enum class VelodyneReturnMode : uint8_t { kStrongest = 0x37, kLast = 0x38, kDual = 0x39 };

// What a point is among the returns of its firing. In dual-return mode "first" is the nearer return
// and "strongest" the one with the higher intensity; kDualOnly marks a firing whose two returns are
// the same (the sensor repeats the strongest when it is also the last) or whose other return is empty.
enum class VelodyneReturnType : uint8_t {
  kStrongest,
  kLast,
  kDualOnly,
  kDualFirstStrongest,
  kDualFirstWeak,
  kDualLastStrongest,
  kDualLastWeak,
};

struct VelodynePoint {
  float x = 0, y = 0, z = 0;  // [m] x forward, y left, z up
  float intensity = 0;        // 0..255
  float distance = 0;         // [m] corrected range
  float azimuth = 0;          // [rad] corrected azimuth, clockwise from x, [0, 2 pi), 0.01 deg steps
  float elevation = 0;        // [rad] the laser's elevation
  int64_t time_ns = 0;        // [ns] firing time: the packet's stamp plus the firing's offset in it
  uint16_t ring = 0;          // 0 = lowest elevation (VelodyneLaserCalibration::ring)
  uint16_t laser_id = 0;      // index in the packet's firing order
  VelodyneReturnType return_type = VelodyneReturnType::kStrongest;
  uint8_t block = 0;  // data block in its packet, 0..11
};

// The fixed fields of a packet, read without decoding its points.
struct VelodynePacketHeader {
  uint32_t gps_time_us = 0;                      // bytes 1200-1203: microseconds past the hour (top of the hour, UTC)
  uint8_t return_mode = 0;                       // byte 1204
  uint8_t product_id = 0;                        // byte 1205
  uint16_t first_azimuth = 0, last_azimuth = 0;  // [0.01 deg] of blocks 0 and 11
};
// nullopt when the packet is not kVelodynePacketSize bytes long.
std::optional<VelodynePacketHeader> read_velodyne_packet_header(std::span<const uint8_t> packet);

enum class VelodynePacketStatus {
  kOk,
  kTruncated,   // shorter than 1206 bytes
  kMalformed,   // longer than 1206 bytes, unknown block id, azimuth >= 360 deg, unknown return mode
  kWrongModel,  // the product id names another model than the configured one
  kOutOfOrder,  // (assembler) dropped: its stamp or its azimuth goes back within the sweep
};
std::string_view to_string(VelodynePacketStatus status);

struct VelodyneDecoderOptions {
  std::optional<VelodyneModel> model;             // nullopt: from each packet's product id
  std::optional<VelodyneReturnMode> return_mode;  // nullopt: from each packet's byte 1204 (the HDL-64E
                                                  // has none: strongest unless set)
  double min_range = 0.4;                         // [m] a point is kept when min < distance < max
  double max_range = 200.0;                       // [m]
  double sector_min_deg = 0.0;                    // kept when the corrected azimuth lies in
  double sector_max_deg = 360.0;                  // [min, max] (wrapping through 0 when min > max)
  double rpm = 600.0;  // nominal speed, only for a packet whose own azimuths give no rate (VLS-128 dual)
};

// Decodes packets one at a time. Per point: distance = raw * unit + dist_correction (unit from the
// manual: 2 mm, 4 mm for the VLP-32C and VLS-128); firing time from the model's timing table;
// azimuth = block azimuth + rotation rate * (firing time - block time) - rot_correction, with the rate
// from the next firing sequence's azimuth in the same packet (the last sequence reuses the previous
// rate), rounded to the sensor's 0.01 deg; then the per-laser offsets of the calibration.
class VelodyneDecoder {
 public:
  VelodyneDecoder(VelodyneCalibration calibration, VelodyneDecoderOptions options);

  // Appends the packet's points to `out` (nothing unless kOk). `stamp_ns` is the time of the packet's
  // first firing (the recorder's stamp or the GPS time).
  VelodynePacketStatus decode(std::span<const uint8_t> packet, int64_t stamp_ns, std::vector<VelodynePoint>& out);

  // The model of the last packet decoded (or the configured one).
  std::optional<VelodyneModel> model() const { return model_; }
  const VelodyneCalibration& calibration() const { return calibration_; }
  const VelodyneDecoderOptions& options() const { return options_; }

 private:
  struct Packet;  // one packet's validated blocks (velodyne.cpp)
  // The steps of decode(): the packet's model and return mode; its blocks' banks, azimuths and times
  // (false when one is malformed); the rotation rate per block; the points.
  VelodynePacketStatus identify(std::span<const uint8_t> packet, Packet& p);
  static bool read_blocks(std::span<const uint8_t> packet, Packet& p);
  void rotation_rates(Packet& p);
  void emit_points(std::span<const uint8_t> packet, const Packet& p, int64_t stamp_ns,
                   std::vector<VelodynePoint>& out) const;
  bool make_point(const Packet& p, std::size_t block, std::size_t channel, uint16_t raw, uint8_t raw_intensity,
                  VelodynePoint& point) const;

  VelodyneCalibration calibration_;
  VelodyneDecoderOptions options_;
  std::optional<VelodyneModel> model_;
  std::vector<double> cos_elev_, sin_elev_;
  std::vector<double> rot_correction_h_;  // [0.01 deg]
  std::vector<double> cos_az_, sin_az_;   // per 0.01 deg
  double last_rate_h_per_us_ = 0.0;       // [0.01 deg / us] from the last packet that gave one
};

// ---------------------------------------------------------------------------------------------
// Sweeps

struct VelodyneSweep {
  int64_t stamp_ns = 0;      // stamp of the packet holding the first point: the time origin
  int64_t end_stamp_ns = 0;  // stamp of the last packet
  uint32_t packets = 0;      // packets that contributed
  uint32_t first_gps_time_us = 0;
  bool complete = true;  // false: ended by a gap, a reset or the end of the stream
  std::vector<VelodynePoint> points;

  double time_offset_s(const VelodynePoint& p) const { return 1e-9 * static_cast<double>(p.time_ns - stamp_ns); }
};

struct VelodyneSweepStats {
  uint64_t packets = 0;       // fed
  uint64_t decoded = 0;       // decoded into points
  uint64_t truncated = 0;     // shorter than a packet
  uint64_t malformed = 0;     // too long, bad block id / azimuth / return mode, wrong model
  uint64_t out_of_order = 0;  // stamp before the previous packet's, or azimuth back within a sweep
  uint64_t gaps = 0;          // more than max_gap_ns after the previous packet
  uint64_t sweeps = 0;        // emitted (complete or not)
  uint64_t incomplete_sweeps = 0;
  uint64_t points = 0;  // in emitted sweeps
};

struct VelodyneSweepOptions {
  double scan_phase_deg = 0.0;      // the cut angle: a sweep runs from it round to it again
  int64_t max_gap_ns = 50'000'000;  // a longer silence ends the sweep (incomplete) and drops carried points
  bool emit_incomplete = true;      // also emit sweeps ended by a gap / flush (marked complete = false)
  bool emit_first = true;           // emit the first sweep of the stream and the first after a silence
                                    // (> max_gap_ns), which start wherever the packets start

  // Whole turns only: neither a first sweep (of the stream or after a silence) nor one cut short. The
  // importer (cdc-import bag) and the driver (cdc-velodyne) both cut so, and make the same sweeps of the
  // same packets.
  static VelodyneSweepOptions whole_turns(double scan_phase_deg) {
    VelodyneSweepOptions o;
    o.scan_phase_deg = scan_phase_deg;
    o.emit_incomplete = false;
    o.emit_first = false;
    return o;
  }
};

// Assembles sweeps from packets fed in arrival order. A sweep ends with the packet in which the
// (phase-shifted) block azimuth wraps: its last block's azimuth is below its first's, or its first is
// below the previous packet's first. Its points at the end that already lie past the cut angle (up to a
// quarter turn past it), taken back from the last point to the first that does not, open the next
// sweep. A point past the cut that precedes one before it stays (per-laser azimuth offsets interleave
// them), so a sweep may overlap the next by the spread of those offsets; this is the reference
// decoder's (nebula's) cut.
// Bad packets are counted and skipped; nothing here throws on packet content.
class VelodyneSweepAssembler {
 public:
  VelodyneSweepAssembler(VelodyneCalibration calibration, VelodyneDecoderOptions decoder_options,
                         VelodyneSweepOptions sweep_options = {});

  // Feeds one datagram (the UDP payload as received) and its arrival stamp. Returns the packet's status;
  // completed sweeps queue up for take().
  VelodynePacketStatus add_packet(std::span<const uint8_t> payload, int64_t stamp_ns);
  bool has_sweep() const { return !ready_.empty(); }
  VelodyneSweep take();  // the oldest completed sweep; call only when has_sweep()
  void flush();          // ends the sweep in progress (incomplete) at the end of a stream
  const VelodyneSweepStats& stats() const { return stats_; }
  const VelodyneDecoder& decoder() const { return decoder_; }

 private:
  void finish(bool complete, uint32_t last_gps_time_us);
  uint32_t phased(uint16_t azimuth) const;

  VelodyneDecoder decoder_;
  VelodyneSweepOptions options_;
  uint32_t phase_h_ = 0;
  VelodyneSweep current_;
  bool have_previous_ = false;
  int64_t previous_stamp_ns_ = 0;
  uint32_t previous_first_phased_ = 0;
  bool first_sweep_ = true;
  std::vector<VelodynePoint> scratch_;
  std::deque<VelodyneSweep> ready_;
  VelodyneSweepStats stats_;
};

// A sweep as the rest of the system takes it: points in the sensor frame, time offsets [s] from its
// earliest point (whose time goes to `stamp_ns`: points carried over the cut may precede the sweep's
// first packet), rings, intensity scaled from 0..255 to 0..1. Every return is kept (both of a
// dual-return firing).
Sweep to_sweep(const VelodyneSweep& sweep, int64_t& stamp_ns);

}  // namespace cdc::io
