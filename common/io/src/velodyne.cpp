#include "cdc/io/velodyne.hpp"

#include "cdc/base/names.hpp"
#include "cdc/io/error.hpp"

#include "yaml_file.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <numbers>
#include <optional>
#include <sstream>
#include <stdexcept>

namespace cdc::io {
namespace {

constexpr std::size_t kBlocks = 12;
constexpr std::size_t kBlockSize = 100;
constexpr std::size_t kChannelsPerBlock = 32;
constexpr int kAzimuthUnits = 36000;  // 0.01 deg per unit
constexpr double kDegToRad = std::numbers::pi / 180.0;

constexpr std::array<base::Named<VelodyneModel>, 6> kModelNames{{{VelodyneModel::kVLP16, "VLP16"},
                                                                 {VelodyneModel::kVLP32C, "VLP32C"},
                                                                 {VelodyneModel::kHDL32E, "HDL32E"},
                                                                 {VelodyneModel::kHDL64E, "HDL64E"},
                                                                 {VelodyneModel::kHDL64ES3, "HDL64E_S3"},
                                                                 {VelodyneModel::kVLS128, "VLS128"}}};
constexpr std::array<base::Named<VelodynePacketStatus>, 5> kPacketStatusNames{
    {{VelodynePacketStatus::kOk, "ok"},
     {VelodynePacketStatus::kTruncated, "truncated"},
     {VelodynePacketStatus::kMalformed, "malformed"},
     {VelodynePacketStatus::kWrongModel, "wrong model"},
     {VelodynePacketStatus::kOutOfOrder, "out of order"}}};

uint16_t read_u16(std::span<const uint8_t> b, std::size_t at) {
  return static_cast<uint16_t>(b[at] | (b[at + 1] << 8));
}

// ---------------------------------------------------------------------------------------------
// Built-in tables (user manuals). Elevation [deg] per laser id; azimuth offsets in the calibration
// files' sign (subtracted from the sensor's azimuth) [deg].

constexpr std::array<double, 16> kVlp16Elevation = {-15, 1, -13, 3, -11, 5, -9, 7, -7, 9, -5, 11, -3, 13, -1, 15};

constexpr std::array<double, 32> kHdl32Elevation = {-30.67, -9.33, -29.33, -8.00, -28.00, -6.67, -26.67, -5.33,
                                                    -25.33, -4.00, -24.00, -2.67, -22.67, -1.33, -21.33, 0.00,
                                                    -20.00, 1.33,  -18.67, 2.67,  -17.33, 4.00,  -16.00, 5.33,
                                                    -14.67, 6.67,  -13.33, 8.00,  -12.00, 9.33,  -10.67, 10.67};

constexpr std::array<double, 32> kVlp32cElevation = {-25,    -1,    -1.667, -15.639, -11.31, 0,     -0.667, -8.843,
                                                     -7.254, 0.333, -0.333, -6.148,  -5.333, 1.333, 0.667,  -4,
                                                     -4.667, 1.667, 1,      -3.667,  -3.333, 3.333, 2.333,  -2.667,
                                                     -3,     7,     4.667,  -2.333,  -2,     15,    10.333, -1.333};
constexpr std::array<double, 32> kVlp32cRotation = {-1.4, 4.2,  -1.4, 1.4,  -1.4, 1.4,  -4.2, 1.4,  -1.4, 4.2,  -1.4,
                                                    1.4,  -4.2, 1.4,  -4.2, 1.4,  -1.4, 4.2,  -1.4, 4.2,  -4.2, 1.4,
                                                    -1.4, 1.4,  -1.4, 1.4,  -1.4, 4.2,  -4.2, 1.4,  -1.4, 1.4};

constexpr std::array<double, 128> kVls128Elevation = {
    -11.742, -1.99, 3.4,   -5.29,  -0.78, 4.61,  -4.08, 1.31,    -6.5,  -1.11,   4.28,   -4.41, 0.1,     6.48,  -3.2,
    2.19,    -3.86, 1.53,  -9.244, -1.77, 2.74,  -5.95, -0.56,   4.83,  -2.98,   2.41,   -6.28, -0.89,   3.62,  -5.07,
    0.32,    7.58,  -0.34, 5.18,   -3.64, 1.75,  -25,   -2.43,   2.96,  -5.73,   0.54,   9.7,   -2.76,   2.63,  -7.65,
    -1.55,   3.84,  -4.85, 3.18,   -5.51, -0.12, 5.73,  -4.3,    1.09,  -16.042, -2.21,  4.06,  -4.63,   0.76,  15,
    -3.42,   1.97,  -6.85, -1.33,  -5.62, -0.23, 5.43,  -3.53,   0.98,  -19.582, -2.32,  3.07,  -4.74,   0.65,  11.75,
    -2.65,   1.86,  -7.15, -1.44,  3.95,  -2.1,  3.29,  -5.4,    -0.01, 4.5,     -4.19,  1.2,   -13.565, -1.22, 4.17,
    -4.52,   0.87,  6.08,  -3.31,  2.08,  -6.65, 1.42,  -10.346, -1.88, 3.51,    -6.06,  -0.67, 4.72,    -3.97, 2.3,
    -6.39,   -1,    4.39,  -5.18,  0.21,  6.98,  -3.09, 4.98,    -3.75, 1.64,    -8.352, -2.54, 2.85,    -5.84, -0.45,
    8.43,    -2.87, 2.52,  -6.17,  -1.66, 3.73,  -4.96, 0.43};
// The VLS-128 fires 8 lasers at once, each in its own azimuth column (laser id mod 8).
constexpr std::array<double, 8> kVls128Rotation = {-6.354, -4.548, -2.732, -0.911, 0.911, 2.732, 4.548, 6.354};

// Distance unit of the packet format [m] (user manuals).
double distance_unit(VelodyneModel model) {
  switch (model) {
    case VelodyneModel::kVLP32C:
    case VelodyneModel::kVLS128:
      return 0.004;
    default:
      return 0.002;
  }
}

// ---------------------------------------------------------------------------------------------
// Firing timing (user manuals), in microseconds from the packet's first firing.

struct Firing {
  int laser = 0;        // laser id
  double time_us = 0;   // firing time
  double block_us = 0;  // time at which the block's azimuth was sampled (its firing sequence's start)
};

constexpr double kVlp16Sequence = 55.296, kVlp16Firing = 2.304;  // 16 firings + recharge
constexpr double kVlp32Sequence = 55.296, kVlp32Firing = 2.304;  // 16 pairs of lasers + recharge
constexpr double kHdl32Block = 46.08, kHdl32Firing = 1.152;      // 32 firings + 8 recharge slots

// HDL-64E "laser firing time table": a firing of an upper and a lower block (one laser of each at a time)
// takes `cycle_us`; each block's 32 lasers fire in 8 groups of 4, a group every `group_us`, the lasers
// of a group at the offsets `in_group_us`.
struct Hdl64Timing {
  double cycle_us, group_us;
  std::array<double, 4> in_group_us;
};
constexpr Hdl64Timing kHdl64S2{48.0, 6.0, {0.0, 1.26, 2.46, 3.66}};  // S2 / S2.1 manual
constexpr Hdl64Timing kHdl64S3{57.6, 7.2, {0.0, 1.3, 2.5, 3.7}};     // S3 manual

bool is_hdl64e(VelodyneModel model) { return model == VelodyneModel::kHDL64E || model == VelodyneModel::kHDL64ES3; }
constexpr double kVls128Sequence = 53.3, kVls128Firing = 2.665, kVls128PacketOffset = -8.7;

// `bank` is the 32-laser group the block id names (0 for the single-bank models).
Firing firing(VelodyneModel model, bool dual, std::size_t block, std::size_t channel, int bank) {
  Firing f;
  const auto b = static_cast<double>(block);
  const auto c = static_cast<double>(channel);
  switch (model) {
    case VelodyneModel::kVLP16: {
      // Two firing sequences of the 16 lasers per block; in dual mode blocks 2k and 2k+1 share them.
      const double first_sequence = dual ? 2.0 * static_cast<double>(block / 2) : 2.0 * b;
      const auto sequence = first_sequence + static_cast<double>(channel / 16);
      f.laser = static_cast<int>(channel % 16);
      f.time_us = sequence * kVlp16Sequence + static_cast<double>(channel % 16) * kVlp16Firing;
      f.block_us = first_sequence * kVlp16Sequence;
      break;
    }
    case VelodyneModel::kVLP32C: {
      const double sequence = dual ? static_cast<double>(block / 2) : b;
      f.laser = static_cast<int>(channel);
      f.time_us = sequence * kVlp32Sequence + static_cast<double>(channel / 2) * kVlp32Firing;
      f.block_us = sequence * kVlp32Sequence;
      break;
    }
    case VelodyneModel::kHDL32E: {
      const double sequence = dual ? static_cast<double>(block / 2) : b;
      f.laser = static_cast<int>(channel);
      f.time_us = sequence * kHdl32Block + c * kHdl32Firing;
      f.block_us = sequence * kHdl32Block;
      break;
    }
    case VelodyneModel::kHDL64E:
    case VelodyneModel::kHDL64ES3: {
      // An upper (0xEEFF) and a lower (0xDDFF) laser fire together: single return packs one firing of
      // both blocks in blocks 2k, 2k+1; dual return packs both returns of one firing in blocks 4k..4k+3.
      const Hdl64Timing& t = model == VelodyneModel::kHDL64ES3 ? kHdl64S3 : kHdl64S2;
      const double sequence = dual ? static_cast<double>(block / 4) : static_cast<double>(block / 2);
      f.laser = bank * 32 + static_cast<int>(channel);
      f.time_us = sequence * t.cycle_us + static_cast<double>(channel / 4) * t.group_us + t.in_group_us[channel % 4];
      f.block_us = sequence * t.cycle_us;
      break;
    }
    case VelodyneModel::kVLS128: {
      // Four blocks (banks) per firing sequence in single return, one sequence in blocks 0..7 in dual.
      // 16 groups of 8 lasers fire 2.665 us apart, with one idle slot after the 8th group.
      const double sequence = dual ? 0.0 : static_cast<double>(block / 4);
      f.laser = bank * 32 + static_cast<int>(channel);
      const int group = f.laser / 8;
      f.time_us =
          sequence * kVls128Sequence + static_cast<double>(group + group / 8) * kVls128Firing + kVls128PacketOffset;
      f.block_us = sequence * kVls128Sequence + kVls128PacketOffset;
      break;
    }
  }
  return f;
}

// Bank of a block id for the model, -1 when the id is not one the model sends.
int bank_of(VelodyneModel model, uint16_t block_id) {
  switch (model) {
    case VelodyneModel::kHDL64E:
    case VelodyneModel::kHDL64ES3:
      return block_id == 0xEEFF ? 0 : block_id == 0xDDFF ? 1 : -1;
    case VelodyneModel::kVLS128:
      switch (block_id) {
        case 0xEEFF:
          return 0;
        case 0xDDFF:
          return 1;
        case 0xCCFF:
          return 2;
        case 0xBBFF:
          return 3;
        default:
          return -1;
      }
    default:
      return block_id == 0xEEFF ? 0 : -1;
  }
}

// In dual return mode, the block holding the other return of block b's firing.
struct DualPartner {
  std::size_t block = 0;
  bool later = false;            // b is the second block of the two
  bool strongest_block = false;  // b is the block that carries the strongest return
};
DualPartner dual_partner(VelodyneModel model, std::size_t b) {
  if (is_hdl64e(model)) {  // blocks 4k, 4k+1: upper, lower of the strongest return; 4k+2, 4k+3: of the last
    const bool strongest = b % 4 < 2;
    return {strongest ? b + 2 : b - 2, !strongest, strongest};
  }
  const bool odd = b % 2 == 1;  // blocks 2k: the last return; 2k+1: the strongest
  return {odd ? b - 1 : b + 1, odd, odd};
}

// What a return is among the returns of its firing; nullopt for the second copy of a repeated return.
std::optional<VelodyneReturnType> return_type(std::span<const uint8_t> packet, VelodyneModel model,
                                              VelodyneReturnMode mode, std::size_t b, std::size_t ch) {
  if (mode != VelodyneReturnMode::kDual) {
    return mode == VelodyneReturnMode::kLast ? VelodyneReturnType::kLast : VelodyneReturnType::kStrongest;
  }
  const DualPartner partner = dual_partner(model, b);
  const std::size_t at = b * kBlockSize + 4 + 3 * ch;
  const std::size_t other_at = partner.block * kBlockSize + 4 + 3 * ch;
  const uint16_t raw = read_u16(packet, at), other = read_u16(packet, other_at);
  const uint8_t raw_intensity = packet[at + 2], other_intensity = packet[other_at + 2];
  if (other == raw || other == 0) {
    if (other == raw && partner.later) return std::nullopt;  // the sensor repeated the return: keep one point
    return VelodyneReturnType::kDualOnly;
  }
  const bool first = raw < other;
  // Equal intensity: the block that carries the strongest return decides.
  const bool strongest = raw_intensity != other_intensity ? raw_intensity > other_intensity : partner.strongest_block;
  if (first) return strongest ? VelodyneReturnType::kDualFirstStrongest : VelodyneReturnType::kDualFirstWeak;
  return strongest ? VelodyneReturnType::kDualLastStrongest : VelodyneReturnType::kDualLastWeak;
}

struct SensorXyz {
  double x = 0, y = 0, z = 0;  // the sensor's own frame: x right, y forward, z up
};

// A return at `distance` along the laser's line at the azimuth (ca, sa) and elevation (cv, sv), with the
// per-laser origin offsets, then the two-point distance correction of the HDL-64E, which interpolates
// the correction on |x| and |y|.
SensorXyz sensor_xyz(const VelodyneLaserCalibration& l, double distance, double ca, double sa, double cv, double sv) {
  const double vo = l.vert_offset_correction, ho = l.horiz_offset_correction;
  double dx = 0, dy = 0;
  if (l.two_pt_correction) {
    const double xy0 = distance * cv - vo * sv;
    const double xx = std::abs(xy0 * sa - ho * ca), yy = std::abs(xy0 * ca + ho * sa);
    dx = (l.dist_correction - l.dist_correction_x) * (xx - 2.4) / (25.04 - 2.4) + l.dist_correction_x -
         l.dist_correction;
    dy = (l.dist_correction - l.dist_correction_y) * (yy - 1.93) / (25.04 - 1.93) + l.dist_correction_y -
         l.dist_correction;
  }
  SensorXyz s;
  s.x = ((distance + dx) * cv - vo * sv) * sa - ho * ca;
  s.y = ((distance + dy) * cv - vo * sv) * ca + ho * sa;
  s.z = (distance + dy) * sv + vo * cv;
  return s;
}

// The intensity with the calibration's focal model (HDL-64E), clamped to its limits.
double corrected_intensity(const VelodyneLaserCalibration& l, uint16_t raw, uint8_t raw_intensity) {
  double intensity = raw_intensity;
  if (l.focal_slope != 0.0) {
    const double focal = 1.0 - l.focal_distance / 13100.0;
    const double near = 1.0 - static_cast<double>(raw) / 65535.0;
    intensity += l.focal_slope * std::abs(256.0 * focal * focal - 256.0 * near * near);
  }
  return std::clamp(intensity, l.min_intensity, l.max_intensity);
}

std::string upper_alnum(std::string_view s) {
  std::string out;
  for (const char ch : s) {
    if (std::isalnum(static_cast<unsigned char>(ch)) != 0)
      out.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(ch))));
  }
  return out;
}

void assign_rings(VelodyneCalibration& c) {
  std::vector<std::size_t> order(c.lasers.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    return c.lasers[a].vert_correction < c.lasers[b].vert_correction;
  });
  for (std::size_t r = 0; r < order.size(); ++r) c.lasers[order[r]].ring = static_cast<int>(r);
}

// Reads the entries of a calibration file; every error names the file and the entry.
struct CalibrationFile {
  std::string file;

  // The number at `key`; `fallback` when the key is absent, an error when it is absent and required.
  double number(const YAML::Node& node, const char* key, const std::string& where,
                std::optional<double> fallback = std::nullopt) const {
    const YAML::Node v = node[key];
    if (!v) {
      if (!fallback) throw FormatError(file + ": " + where + ": missing key '" + key + "'");
      return *fallback;
    }
    double x = 0;
    try {
      x = v.as<double>();
    } catch (const YAML::Exception&) {
      throw FormatError(file + ": " + where + ": '" + key + "' is not a number");
    }
    if (!std::isfinite(x)) throw FormatError(file + ": " + where + ": '" + key + "' is not a finite number");
    return x;
  }

  // One entry of `lasers` (all but its laser_id).
  VelodyneLaserCalibration laser(const YAML::Node& e, const std::string& where) const {
    VelodyneLaserCalibration l;
    l.rot_correction = number(e, "rot_correction", where);
    l.vert_correction = number(e, "vert_correction", where);
    l.dist_correction = number(e, "dist_correction", where);
    l.dist_correction_x = number(e, "dist_correction_x", where, 0.0);
    l.dist_correction_y = number(e, "dist_correction_y", where, 0.0);
    if (const YAML::Node t = e["two_pt_correction_available"]) {
      try {
        l.two_pt_correction = t.as<bool>();
      } catch (const YAML::Exception&) {
        throw FormatError(file + ": " + where + ": 'two_pt_correction_available' is not a boolean");
      }
    }
    l.vert_offset_correction = number(e, "vert_offset_correction", where, 0.0);
    l.horiz_offset_correction = number(e, "horiz_offset_correction", where, 0.0);
    l.focal_distance = number(e, "focal_distance", where, 0.0);
    l.focal_slope = number(e, "focal_slope", where, 0.0);
    l.min_intensity = std::floor(number(e, "min_intensity", where, 0.0));
    l.max_intensity = std::floor(number(e, "max_intensity", where, 255.0));
    if (std::abs(l.vert_correction) > std::numbers::pi / 2 || std::abs(l.rot_correction) > std::numbers::pi) {
      throw FormatError(file + ": " + where + ": vert_correction / rot_correction out of range (radians expected)");
    }
    return l;
  }
};

}  // namespace

// ---------------------------------------------------------------------------------------------

std::string_view to_string(VelodyneModel model) { return base::name_of(kModelNames, model, "unknown"); }

VelodyneModel velodyne_model_from_string(std::string_view name) {
  const std::string n = upper_alnum(name);
  if (n == "VLP16" || n == "PUCK" || n == "VLP16HIRES") return VelodyneModel::kVLP16;
  if (n == "VLP32C" || n == "VLP32") return VelodyneModel::kVLP32C;
  if (n == "HDL32E" || n == "HDL32") return VelodyneModel::kHDL32E;
  if (n == "HDL64E" || n == "HDL64" || n == "HDL64ES2" || n == "HDL64ES21") return VelodyneModel::kHDL64E;
  if (n == "HDL64ES3") return VelodyneModel::kHDL64ES3;
  if (n == "VLS128" || n == "ALPHAPRIME") return VelodyneModel::kVLS128;
  throw std::invalid_argument("unknown Velodyne model '" + std::string(name) +
                              "' (expected VLP16, VLP32C, HDL32E, HDL64E (S2), HDL64E_S3 or VLS128)");
}

std::optional<VelodyneModel> velodyne_model_from_product_id(uint8_t product_id) {
  switch (product_id) {
    case 0x21:
      return VelodyneModel::kHDL32E;
    case 0x22:
    case 0x24:
      return VelodyneModel::kVLP16;
    case 0x28:
      return VelodyneModel::kVLP32C;
    case 0xA1:
      return VelodyneModel::kVLS128;
    default:
      return std::nullopt;
  }
}

int velodyne_laser_count(VelodyneModel model) {
  switch (model) {
    case VelodyneModel::kVLP16:
      return 16;
    case VelodyneModel::kVLP32C:
    case VelodyneModel::kHDL32E:
      return 32;
    case VelodyneModel::kHDL64E:
    case VelodyneModel::kHDL64ES3:
      return 64;
    case VelodyneModel::kVLS128:
      return 128;
  }
  return 0;
}

std::string_view to_string(VelodynePacketStatus status) { return base::name_of(kPacketStatusNames, status, "unknown"); }

// ---------------------------------------------------------------------------------------------
// Calibration

VelodyneCalibration read_velodyne_calibration(const std::filesystem::path& path, std::optional<VelodyneModel> model) {
  const std::string file = path.string();
  const YAML::Node root = detail::load_yaml_file(file);
  if (!root.IsMap()) throw FormatError(file + ": expected a map with num_lasers and lasers");
  const CalibrationFile f{file};
  VelodyneCalibration c;
  c.source = file;
  const double num = f.number(root, "num_lasers", "top level");
  if (num < 1 || num > 128 || num != std::floor(num)) {
    throw FormatError(file + ": num_lasers must be a whole number in 1..128, not " + std::to_string(num));
  }
  const auto n = static_cast<std::size_t>(num);
  c.distance_resolution = f.number(root, "distance_resolution", "top level", 0.0);
  const YAML::Node lasers = root["lasers"];
  if (!lasers || !lasers.IsSequence()) throw FormatError(file + ": missing sequence 'lasers'");
  if (lasers.size() != n) {
    throw FormatError(file + ": num_lasers is " + std::to_string(n) + " but 'lasers' has " +
                      std::to_string(lasers.size()) + " entries");
  }
  if (model && static_cast<int>(n) != velodyne_laser_count(*model)) {
    throw FormatError(file + ": " + std::to_string(n) + " lasers, but a " + std::string(to_string(*model)) + " has " +
                      std::to_string(velodyne_laser_count(*model)));
  }
  c.lasers.resize(n);
  std::vector<bool> seen(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    const YAML::Node e = lasers[i];
    const std::string where = "lasers[" + std::to_string(i) + "]";
    if (!e.IsMap()) throw FormatError(file + ": " + where + " is not a map");
    const double id = f.number(e, "laser_id", where);
    if (id < 0 || id >= static_cast<double>(n) || id != std::floor(id)) {
      throw FormatError(file + ": " + where + ": laser_id " + std::to_string(id) + " is not in 0.." +
                        std::to_string(n - 1));
    }
    const auto k = static_cast<std::size_t>(id);
    if (seen[k]) throw FormatError(file + ": " + where + ": laser_id " + std::to_string(k) + " appears twice");
    seen[k] = true;
    c.lasers[k] = f.laser(e, where);
    c.lasers[k].laser_id = static_cast<int>(k);
  }
  assign_rings(c);
  return c;
}

VelodyneCalibration default_velodyne_calibration(VelodyneModel model) {
  VelodyneCalibration c;
  c.source = "built-in " + std::string(to_string(model));
  c.distance_resolution = distance_unit(model);
  const auto n = static_cast<std::size_t>(velodyne_laser_count(model));
  c.lasers.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    auto& l = c.lasers[i];
    l.laser_id = static_cast<int>(i);
    double elevation = 0, rotation = 0;
    switch (model) {
      case VelodyneModel::kVLP16:
        elevation = kVlp16Elevation[i];
        break;
      case VelodyneModel::kHDL32E:
        elevation = kHdl32Elevation[i];
        break;
      case VelodyneModel::kVLP32C:
        elevation = kVlp32cElevation[i];
        rotation = kVlp32cRotation[i];
        break;
      case VelodyneModel::kVLS128:
        elevation = kVls128Elevation[i];
        rotation = kVls128Rotation[i % 8];
        break;
      case VelodyneModel::kHDL64E:
      case VelodyneModel::kHDL64ES3:
        elevation = i < 32 ? 2.0 - static_cast<double>(i) / 3.0 : -8.83 - 0.5 * static_cast<double>(i - 32);
        break;
    }
    l.vert_correction = elevation * kDegToRad;
    l.rot_correction = rotation * kDegToRad;
  }
  assign_rings(c);
  return c;
}

// ---------------------------------------------------------------------------------------------
// Decoder

std::optional<VelodynePacketHeader> read_velodyne_packet_header(std::span<const uint8_t> packet) {
  if (packet.size() != kVelodynePacketSize) return std::nullopt;
  VelodynePacketHeader h;
  h.gps_time_us = static_cast<uint32_t>(packet[1200]) | (static_cast<uint32_t>(packet[1201]) << 8) |
                  (static_cast<uint32_t>(packet[1202]) << 16) | (static_cast<uint32_t>(packet[1203]) << 24);
  h.return_mode = packet[1204];
  h.product_id = packet[1205];
  h.first_azimuth = read_u16(packet, 2);
  h.last_azimuth = read_u16(packet, (kBlocks - 1) * kBlockSize + 2);
  return h;
}

VelodyneDecoder::VelodyneDecoder(VelodyneCalibration calibration, VelodyneDecoderOptions options)
    : calibration_(std::move(calibration)), options_(options), model_(options.model) {
  if (calibration_.lasers.empty()) throw std::invalid_argument("Velodyne decoder: calibration has no lasers");
  if (options_.model && static_cast<int>(calibration_.lasers.size()) != velodyne_laser_count(*options_.model)) {
    throw std::invalid_argument("Velodyne decoder: calibration " + calibration_.source + " has " +
                                std::to_string(calibration_.lasers.size()) + " lasers, a " +
                                std::string(to_string(*options_.model)) + " has " +
                                std::to_string(velodyne_laser_count(*options_.model)));
  }
  if (!(options_.min_range >= 0 && options_.max_range > options_.min_range)) {
    throw std::invalid_argument("Velodyne decoder: need 0 <= min_range < max_range");
  }
  for (const auto& l : calibration_.lasers) {
    cos_elev_.push_back(std::cos(l.vert_correction));
    sin_elev_.push_back(std::sin(l.vert_correction));
    rot_correction_h_.push_back(l.rot_correction / kDegToRad * 100.0);
  }
  cos_az_.resize(kAzimuthUnits);
  sin_az_.resize(kAzimuthUnits);
  for (int i = 0; i < kAzimuthUnits; ++i) {
    const double a = static_cast<double>(i) * 0.01 * kDegToRad;
    cos_az_[static_cast<std::size_t>(i)] = std::cos(a);
    sin_az_[static_cast<std::size_t>(i)] = std::sin(a);
  }
}

// The validated blocks of one packet and what the decoder derives from them.
struct VelodyneDecoder::Packet {
  VelodyneModel model = VelodyneModel::kVLP16;
  VelodyneReturnMode mode = VelodyneReturnMode::kStrongest;
  bool dual = false;
  std::size_t used_blocks = kBlocks;
  std::array<int, kBlocks> bank{};
  std::array<uint16_t, kBlocks> azimuth{};  // [0.01 deg]
  std::array<double, kBlocks> block_us{};   // when the block's azimuth was sampled
  std::array<double, kBlocks> rate{};       // [0.01 deg / us] rotation rate from the block on
  double unit = 0.0;                        // [m] distance unit
  long sector_min_h = 0, sector_max_h = 0;  // [0.01 deg]

  bool in_sector(long a) const {
    return sector_min_h <= sector_max_h ? (a >= sector_min_h && a <= sector_max_h)
                                        : (a >= sector_min_h || a <= sector_max_h);
  }
};

VelodynePacketStatus VelodyneDecoder::decode(std::span<const uint8_t> packet, int64_t stamp_ns,
                                             std::vector<VelodynePoint>& out) {
  if (packet.size() < kVelodynePacketSize) return VelodynePacketStatus::kTruncated;
  if (packet.size() > kVelodynePacketSize) return VelodynePacketStatus::kMalformed;
  Packet p;
  if (const auto status = identify(packet, p); status != VelodynePacketStatus::kOk) return status;
  // Validate every block first: a packet is decoded whole or not at all.
  if (!read_blocks(packet, p)) return VelodynePacketStatus::kMalformed;
  rotation_rates(p);
  p.unit = distance_unit(p.model);
  p.sector_min_h = static_cast<long>(std::lround(options_.sector_min_deg * 100.0));
  p.sector_max_h = static_cast<long>(std::lround(options_.sector_max_deg * 100.0));
  emit_points(packet, p, stamp_ns, out);
  return VelodynePacketStatus::kOk;
}

VelodynePacketStatus VelodyneDecoder::identify(std::span<const uint8_t> packet, Packet& p) {
  const auto named = velodyne_model_from_product_id(packet[1205]);
  if (options_.model) {
    p.model = *options_.model;
    // The HDL-64E has no product id: its status bytes may hold anything.
    if (!is_hdl64e(p.model) && named && *named != p.model) return VelodynePacketStatus::kWrongModel;
  } else {
    if (!named) return VelodynePacketStatus::kMalformed;
    p.model = *named;
  }
  if (static_cast<int>(calibration_.lasers.size()) != velodyne_laser_count(p.model))
    return VelodynePacketStatus::kWrongModel;
  model_ = p.model;

  if (options_.return_mode) {
    p.mode = *options_.return_mode;
  } else if (is_hdl64e(p.model)) {
    p.mode = VelodyneReturnMode::kStrongest;
  } else {
    const uint8_t m = packet[1204];
    if (m != 0x37 && m != 0x38 && m != 0x39) return VelodynePacketStatus::kMalformed;
    p.mode = static_cast<VelodyneReturnMode>(m);
  }
  p.dual = p.mode == VelodyneReturnMode::kDual;
  // The VLS-128 packs one firing sequence in blocks 0..7 in dual mode; 8..11 carry nothing.
  p.used_blocks = p.dual && p.model == VelodyneModel::kVLS128 ? 8 : kBlocks;
  return VelodynePacketStatus::kOk;
}

bool VelodyneDecoder::read_blocks(std::span<const uint8_t> packet, Packet& p) {
  for (std::size_t b = 0; b < p.used_blocks; ++b) {
    const std::size_t at = b * kBlockSize;
    p.bank[b] = bank_of(p.model, read_u16(packet, at));
    p.azimuth[b] = read_u16(packet, at + 2);
    if (p.bank[b] < 0 || p.azimuth[b] >= kAzimuthUnits) return false;
    p.block_us[b] = firing(p.model, p.dual, b, 0, p.bank[b]).block_us;
  }
  return true;
}

void VelodyneDecoder::rotation_rates(Packet& p) {
  // Per block: towards the next firing sequence's azimuth in this packet.
  constexpr double kMaxRate = 1.0;  // 1667 rpm: anything faster is a corrupt azimuth
  double packet_rate = -1.0;
  for (std::size_t b = 0; b < p.used_blocks; ++b) {
    p.rate[b] = -1.0;
    for (std::size_t n = b + 1; n < p.used_blocks; ++n) {
      if (p.block_us[n] > p.block_us[b]) {
        const int diff =
            (static_cast<int>(p.azimuth[n]) - static_cast<int>(p.azimuth[b]) + kAzimuthUnits) % kAzimuthUnits;
        const double r = static_cast<double>(diff) / (p.block_us[n] - p.block_us[b]);
        if (r > 0.0 && r <= kMaxRate) {
          p.rate[b] = r;
          packet_rate = r;
        }
        break;
      }
    }
  }
  const double nominal = options_.rpm * 6.0 * 100.0 / 1e6;
  const double fallback = packet_rate > 0 ? packet_rate : last_rate_h_per_us_ > 0 ? last_rate_h_per_us_ : nominal;
  // The last sequence reuses the rate of the one before it.
  for (std::size_t b = p.used_blocks; b-- > 0;) {
    if (p.rate[b] >= 0) continue;
    double previous = -1.0;
    for (std::size_t q = b; q-- > 0;) {
      if (p.rate[q] > 0) {
        previous = p.rate[q];
        break;
      }
    }
    p.rate[b] = previous > 0 ? previous : fallback;
  }
  if (packet_rate > 0) last_rate_h_per_us_ = packet_rate;
}

void VelodyneDecoder::emit_points(std::span<const uint8_t> packet, const Packet& p, int64_t stamp_ns,
                                  std::vector<VelodynePoint>& out) const {
  for (std::size_t b = 0; b < p.used_blocks; ++b) {
    for (std::size_t ch = 0; ch < kChannelsPerBlock; ++ch) {
      const std::size_t at = b * kBlockSize + 4 + 3 * ch;
      const uint16_t raw = read_u16(packet, at);
      if (raw == 0) continue;  // no return
      const std::optional<VelodyneReturnType> type = return_type(packet, p.model, p.mode, b, ch);
      if (!type) continue;
      VelodynePoint point;
      if (!make_point(p, b, ch, raw, packet[at + 2], point)) continue;
      point.time_ns += stamp_ns;
      point.return_type = *type;
      out.push_back(point);
    }
  }
}

bool VelodyneDecoder::make_point(const Packet& p, std::size_t b, std::size_t ch, uint16_t raw, uint8_t raw_intensity,
                                 VelodynePoint& point) const {
  const Firing f = firing(p.model, p.dual, b, ch, p.bank[b]);
  const auto li = static_cast<std::size_t>(f.laser);
  const VelodyneLaserCalibration& l = calibration_.lasers[li];
  const double distance = static_cast<double>(raw) * p.unit + l.dist_correction;
  if (!(distance > options_.min_range && distance < options_.max_range)) return false;

  const double az_f = static_cast<double>(p.azimuth[b]) + p.rate[b] * (f.time_us - f.block_us) - rot_correction_h_[li];
  // Exact halves (common: rates are whole hundredths per sequence) round up whatever the last bit.
  long az = std::lround(az_f + 1e-6) % kAzimuthUnits;
  if (az < 0) az += kAzimuthUnits;
  if (!p.in_sector(az)) return false;

  const auto ai = static_cast<std::size_t>(az);
  const SensorXyz s = sensor_xyz(l, distance, cos_az_[ai], sin_az_[ai], cos_elev_[li], sin_elev_[li]);
  point.x = static_cast<float>(s.y);   // forward
  point.y = static_cast<float>(-s.x);  // left
  point.z = static_cast<float>(s.z);
  point.intensity = static_cast<float>(corrected_intensity(l, raw, raw_intensity));
  point.distance = static_cast<float>(distance);
  point.azimuth = static_cast<float>(static_cast<double>(az) * 0.01 * kDegToRad);
  point.elevation = static_cast<float>(l.vert_correction);
  point.time_ns = std::llround(f.time_us * 1000.0);
  point.ring = static_cast<uint16_t>(l.ring);
  point.laser_id = static_cast<uint16_t>(f.laser);
  point.block = static_cast<uint8_t>(b);
  return true;
}

// ---------------------------------------------------------------------------------------------
// Sweep assembly

VelodyneSweepAssembler::VelodyneSweepAssembler(VelodyneCalibration calibration, VelodyneDecoderOptions decoder_options,
                                               VelodyneSweepOptions sweep_options)
    : decoder_(std::move(calibration), decoder_options), options_(sweep_options) {
  if (!(options_.scan_phase_deg >= 0.0 && options_.scan_phase_deg <= 360.0)) {
    throw std::invalid_argument("Velodyne sweep: scan_phase_deg must lie in [0, 360]");
  }
  phase_h_ = static_cast<uint32_t>(std::lround(options_.scan_phase_deg * 100.0)) % static_cast<uint32_t>(kAzimuthUnits);
}

uint32_t VelodyneSweepAssembler::phased(uint16_t azimuth) const {
  return (static_cast<uint32_t>(azimuth) + static_cast<uint32_t>(kAzimuthUnits) - phase_h_) %
         static_cast<uint32_t>(kAzimuthUnits);
}

void VelodyneSweepAssembler::finish(bool complete, uint32_t last_gps_time_us) {
  std::vector<VelodynePoint> carried;
  if (complete) {
    // Points at the end already past the cut (within a quarter turn) open the next sweep.
    std::size_t keep = current_.points.size();
    while (keep > 0) {
      const auto az = static_cast<uint32_t>(
                          std::lround(static_cast<double>(current_.points[keep - 1].azimuth) / kDegToRad * 100.0)) %
                      static_cast<uint32_t>(kAzimuthUnits);
      if (phased(static_cast<uint16_t>(az)) >= static_cast<uint32_t>(kAzimuthUnits / 4)) break;
      --keep;
    }
    carried.assign(current_.points.begin() + static_cast<std::ptrdiff_t>(keep), current_.points.end());
    current_.points.resize(keep);
  }
  current_.complete = complete;
  const bool emit =
      current_.packets > 0 && (complete || options_.emit_incomplete) && (!first_sweep_ || options_.emit_first);
  if (emit) {
    ++stats_.sweeps;
    if (!complete) ++stats_.incomplete_sweeps;
    stats_.points += current_.points.size();
    ready_.push_back(std::move(current_));
  }
  if (current_.packets > 0) first_sweep_ = false;
  const int64_t end = current_.end_stamp_ns;
  current_ = VelodyneSweep{};
  if (!carried.empty()) {
    current_.points = std::move(carried);
    current_.stamp_ns = end;
    current_.end_stamp_ns = end;
    current_.first_gps_time_us = last_gps_time_us;
  }
}

VelodynePacketStatus VelodyneSweepAssembler::add_packet(std::span<const uint8_t> payload, int64_t stamp_ns) {
  ++stats_.packets;
  const auto header = read_velodyne_packet_header(payload);
  if (!header) {
    if (payload.size() < kVelodynePacketSize) {
      ++stats_.truncated;
      return VelodynePacketStatus::kTruncated;
    }
    ++stats_.malformed;
    return VelodynePacketStatus::kMalformed;
  }
  if (have_previous_ && stamp_ns < previous_stamp_ns_) {
    ++stats_.out_of_order;
    return VelodynePacketStatus::kOutOfOrder;
  }
  const uint32_t first = phased(header->first_azimuth), last = phased(header->last_azimuth);
  bool wrapped_between = false;
  if (have_previous_ && first < previous_first_phased_) {
    // A wrap through the cut angle moves the azimuth back by most of a turn (by less when the sensor
    // sends only a sector); a step back of less than a quarter turn is a packet out of order.
    if (previous_first_phased_ - first >= static_cast<uint32_t>(kAzimuthUnits / 4)) {
      wrapped_between = true;
    } else {
      ++stats_.out_of_order;
      return VelodynePacketStatus::kOutOfOrder;
    }
  }
  scratch_.clear();
  const VelodynePacketStatus status = decoder_.decode(payload, stamp_ns, scratch_);
  if (status != VelodynePacketStatus::kOk) {
    ++stats_.malformed;
    return status;
  }
  ++stats_.decoded;
  if (have_previous_ && stamp_ns - previous_stamp_ns_ > options_.max_gap_ns) {
    ++stats_.gaps;
    if (current_.packets > 0) {
      finish(false, 0);
    } else {
      current_ = VelodyneSweep{};  // only points carried over from before the silence: drop them
    }
    first_sweep_ = true;  // the sweep after a silence starts mid-turn, like the first of a stream
    wrapped_between = false;
  }
  if (current_.points.empty() && current_.packets == 0) {
    current_.stamp_ns = stamp_ns;
    current_.first_gps_time_us = header->gps_time_us;
  }
  current_.points.insert(current_.points.end(), scratch_.begin(), scratch_.end());
  ++current_.packets;
  current_.end_stamp_ns = stamp_ns;
  const bool wrapped_inside = last < first;
  if ((wrapped_between || wrapped_inside) && current_.packets > 1) finish(true, header->gps_time_us);
  have_previous_ = true;
  previous_stamp_ns_ = stamp_ns;
  previous_first_phased_ = first;
  return VelodynePacketStatus::kOk;
}

VelodyneSweep VelodyneSweepAssembler::take() {
  VelodyneSweep s = std::move(ready_.front());
  ready_.pop_front();
  return s;
}

void VelodyneSweepAssembler::flush() {
  if (current_.packets > 0) finish(false, 0);
  current_ = VelodyneSweep{};
  have_previous_ = false;
}

Sweep to_sweep(const VelodyneSweep& v, int64_t& stamp_ns) {
  Sweep s;
  s.has_time = s.has_ring = s.has_intensity = true;
  stamp_ns = v.stamp_ns;
  for (const VelodynePoint& p : v.points) stamp_ns = std::min(stamp_ns, p.time_ns);
  s.points.reserve(v.points.size());
  for (const VelodynePoint& p : v.points) {
    s.points.push_back({p.x, p.y, p.z, p.intensity / 255.0f,
                        static_cast<float>(1e-9 * static_cast<double>(p.time_ns - stamp_ns)), p.ring});
  }
  return s;
}

}  // namespace cdc::io
