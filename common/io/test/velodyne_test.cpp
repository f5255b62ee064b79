// Velodyne decoding and sweep assembly.
//
// Real fixtures (CDC_DATA_DIR/real/packets/velodyne): nebula's (tier4/nebula @ 606ac41f) decoder test
// bags and the reference sweeps it made. The reference decoder departs from the user manuals in a few
// documented places (see NebulaRules below), so each fixture is checked twice:
//   1. our decoder against an independent re-computation with the manuals' formulas (ManualRules): same
//      points in the same order, within 1 mm, same ring / intensity / return type / time;
//   2. the same re-computation with nebula's rules switched on against the reference .pcd: same points
//      in the same order, within 1 mm (and intensity, channel, return type, time for the VLP-16).
// Together they show that every difference between our sweep and the reference comes from one of the
// listed rules. HDL-32E and HDL-64E have no fixture: packets are built here from the manuals' firing
// tables and the decoded geometry and times are checked against the manuals' formulas.
#include "cdc/io/velodyne.hpp"

#include "cdc/io/bag.hpp"
#include "cdc/io/ros_messages.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace cdc::io {
namespace {

constexpr double kPi = std::numbers::pi;

std::filesystem::path data_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return std::filesystem::path(env != nullptr ? env : "../shared/data") / "real" / "packets" / "velodyne";
}

struct RawPacket {
  int64_t bag_ns = 0;  // log time of the message that carried it
  int32_t sec = 0;     // the packet's stamp
  uint32_t nanosec = 0;
  std::array<uint8_t, kVelodynePacketSize> data{};
};

std::vector<RawPacket> read_packets(const std::filesystem::path& bag_dir) {
  std::vector<RawPacket> out;
  auto bag = open_bag(bag_dir);
  BagMessage m;
  while (bag->next(m)) {
    if (m.type != "velodyne_msgs/msg/VelodyneScan") continue;
    const VelodyneScanMsg scan = decode_velodyne_scan(m);
    for (const auto& p : scan.packets) {
      RawPacket r;
      r.bag_ns = m.log_time_ns;
      r.sec = static_cast<int32_t>(p.stamp_ns / 1000000000);
      r.nanosec = static_cast<uint32_t>(p.stamp_ns % 1000000000);
      r.data = p.data;
      out.push_back(r);
    }
  }
  return out;
}

// A point in nebula's terms (its PointXYZIRCAEDT fields that the reference keeps).
struct RefPoint {
  float x = 0, y = 0, z = 0;
  float intensity = 0;
  uint8_t return_type = 0;  // nebula's ReturnType: 1 LAST 3 STRONGEST 4 FIRST_WEAK 5 LAST_WEAK 6 IDENTICAL
                            // 9 FIRST_STRONGEST 10 LAST_STRONGEST
  uint16_t channel = 0;     // ring
  float azimuth = 0;        // [rad]
  int64_t time_ns = 0;      // since the cloud's stamp
};

// Binary PCD with fields x y z [intensity return_type channel azimuth elevation distance time_stamp].
std::vector<RefPoint> read_reference_pcd(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  std::vector<std::string> fields, sizes;
  std::size_t n = 0;
  while (std::getline(in, line)) {
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "FIELDS") {
      for (std::string f; ls >> f;) fields.push_back(f);
    } else if (key == "SIZE") {
      for (std::string f; ls >> f;) sizes.push_back(f);
    } else if (key == "POINTS") {
      ls >> n;
    } else if (key == "DATA") {
      break;
    }
  }
  std::size_t stride = 0;
  std::map<std::string, std::size_t> offset;
  for (std::size_t i = 0; i < fields.size(); ++i) {
    offset[fields[i]] = stride;
    stride += static_cast<std::size_t>(std::stoul(sizes.at(i)));
  }
  std::vector<char> buf(n * stride);
  in.read(buf.data(), static_cast<std::streamsize>(buf.size()));
  if (static_cast<std::size_t>(in.gcount()) != buf.size()) return {};
  // Field f of point i, stored as the type of `stored`, into v (left as it is when the file has no f).
  auto get = [&](std::size_t i, const char* f, auto& v, auto stored) {
    if (offset.count(f) == 0) return;
    std::memcpy(&stored, buf.data() + i * stride + offset[f], sizeof(stored));
    v = stored;
  };
  std::vector<RefPoint> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    RefPoint& p = out[i];
    get(i, "x", p.x, float{});
    get(i, "y", p.y, float{});
    get(i, "z", p.z, float{});
    get(i, "intensity", p.intensity, uint8_t{});
    get(i, "return_type", p.return_type, uint8_t{});
    get(i, "channel", p.channel, uint16_t{});
    get(i, "azimuth", p.azimuth, float{});
    get(i, "time_stamp", p.time_ns, uint32_t{});
  }
  return out;
}

uint16_t u16(const uint8_t* p) { return static_cast<uint16_t>(p[0] | (p[1] << 8)); }

// nebula's return type number of each of ours (0: none).
uint8_t nebula_type(VelodyneReturnType t) {
  using R = VelodyneReturnType;
  constexpr std::pair<R, uint8_t> kNumbers[] = {{R::kStrongest, 3},     {R::kLast, 1},
                                                {R::kDualOnly, 6},      {R::kDualFirstStrongest, 9},
                                                {R::kDualFirstWeak, 4}, {R::kDualLastStrongest, 10},
                                                {R::kDualLastWeak, 5}};
  for (const auto& [type, number] : kNumbers) {
    if (type == t) return number;
  }
  return 0;
}

// ---------------------------------------------------------------------------------------------
// Re-computation of a fixture's sweeps, written from the manuals (kManual) or with the reference
// decoder's own rules (kNebula). nebula's rules, as its decoders apply them:
//  N1 azimuth interpolation uses the azimuth difference to the block 1 + dual further on; in dual
//     mode the odd blocks (second returns) of pairs 0..4 take the next pair's azimuth as their own;
//  N2 the last block (single) / block 10 (VLP-16 dual) is not interpolated (difference 0), and the
//     VLS-128's blocks 0-2, 4-6, 8-10 neither (the next block of the same firing sequence has the same
//     azimuth), nor the VLP-16 dual block 11 (its difference is taken from the equal pair 10/11);
//  N3 VLP-32C: laser j is interpolated at j * 2.304 us although lasers fire in pairs (j / 2, as in
//     its own timing table);
//  N4 the sector is also applied to the block's raw azimuth (VLP-32C: only to it);
//  N5 azimuth sums in single precision before rounding to 0.01 deg (ties may round the other way);
//  N6 VLP-16 dual return types: "first" is the farther return;
//  N7 VLP-32C: the points carried over a cut are never moved (its quarter-turn test lacks the modulo),
//     a VLP-32C point's azimuth is its block's raw azimuth;
//  N8 carried points are dropped when the next packet's stamp is more than 50 ms after them;
//  N9 point times come from a single-precision table, are truncated to whole ns and clipped at 0;
//  N10 the VLP-16 reference's times follow the single-return timing table although the packets are dual;
//  N11 its test stamps each packet with whole seconds (times are offsets within their packet).
enum class Rules { kManual, kNebula };

struct FixtureSettings {
  VelodyneModel model = VelodyneModel::kVLP16;
  double min_range = 0.3, max_range = 300;
  int min_angle = 0, max_angle = 359;  // [deg]
  double phase_deg = 0;
  bool dual_config = false;  // the configured return mode (timing tables); the packets' byte decides the rest
};

class RuleDecoder {
 public:
  RuleDecoder(const VelodyneCalibration& c, FixtureSettings s, Rules rules) : cal_(c), s_(s), rules_(rules) {}

  // Feeds one packet with its stamp; returns the cloud it completes, if any. nebula holds stamps as
  // double seconds (rclcpp::Time::seconds(), 0.24 us steps at this epoch), the manual rules as ns.
  bool feed(const uint8_t* pkt, int64_t stamp_ns, std::vector<RefPoint>& cloud_out) {
    const double stamp_s = static_cast<double>(stamp_ns) / 1e9;
    stamp_ns_ = stamp_ns;
    const auto phase = static_cast<uint32_t>(std::lround(s_.phase_deg * 100));
    if (has_scanned_) {
      processed_ = 0;
      scan_.clear();
      reset_overflow(stamp_s);
    }
    has_scanned_ = false;
    ++processed_;
    const uint32_t first = (36000 + u16(pkt + 2) - phase) % 36000, last = (36000 + u16(pkt + 1102) - phase) % 36000;
    has_scanned_ = processed_ > 1 && (last < first || first < prev_first_);
    prev_first_ = first;
    unpack(pkt, stamp_s);
    if (!has_scanned_) return false;
    // Points at the end past the cut (within a quarter turn) go to the next cloud.
    const double ph = s_.phase_deg * kPi / 180;
    auto past = [&](const RefPoint& p) {
      if (rules_ == Rules::kNebula && s_.model == VelodyneModel::kVLP32C)
        return 2 * kPi + p.azimuth - ph < kPi / 2;  // N7
      return static_cast<std::size_t>((2 * kPi + p.azimuth - ph) * 180 / kPi) % 360 < 90;
    };
    while (!scan_.empty() && past(scan_.back())) {
      overflow_.push_back(scan_.back());
      scan_.pop_back();
    }
    cloud_out = scan_;
    return true;
  }

 private:
  void reset_overflow(double stamp_s) {
    if (overflow_.empty()) {
      scan_ts_ = -1;
      return;
    }
    const double last_overflow = scan_ts_ + 1e-9 * static_cast<double>(overflow_.back().time_ns);
    if (rules_ == Rules::kNebula && stamp_s - last_overflow > 0.05) {  // N8
      scan_ts_ = -1;
      overflow_.clear();
      return;
    }
    while (!overflow_.empty()) {
      RefPoint p = overflow_.back();
      overflow_.pop_back();
      if (rules_ == Rules::kNebula) {
        const double t = scan_ts_ + 1e-9 * static_cast<double>(p.time_ns) - last_block_ts_;
        p.time_ns = static_cast<uint32_t>(t < 0 ? 0 : 1e9 * t);
      } else {
        p.time_ns += scan_ns_ - last_block_ns_;
      }
      scan_.push_back(p);
    }
    scan_ts_ = last_block_ts_;
    scan_ns_ = last_block_ns_;
  }

  bool in_sector(long az) const {
    const long lo = s_.min_angle * 100L, hi = s_.max_angle * 100L;
    return lo < hi ? (az >= lo && az <= hi) : (az <= hi || az >= lo);
  }

  // Firing time [s] of channel j of block b, and the time of the block's azimuth, from the manuals.
  void timing(std::size_t b, std::size_t j, int laser, bool dual, double& t, double& tb) const {
    switch (s_.model) {
      case VelodyneModel::kVLP16: {
        const double seq0 = dual ? static_cast<double>(b - b % 2) : 2.0 * static_cast<double>(b);
        t = 55.296e-6 * (seq0 + static_cast<double>(j / 16)) + 2.304e-6 * static_cast<double>(j % 16);
        tb = 55.296e-6 * seq0;
        break;
      }
      case VelodyneModel::kVLP32C: {
        const double seq = dual ? static_cast<double>(b / 2) : static_cast<double>(b);
        t = 55.296e-6 * seq + 2.304e-6 * static_cast<double>(j / 2);
        tb = 55.296e-6 * seq;
        break;
      }
      default: {  // VLS-128
        const int g = laser / 8;
        const double seq = dual ? 0.0 : static_cast<double>(b / 4);
        t = 53.3e-6 * seq + 2.665e-6 * (g + g / 8) - 8.7e-6;
        tb = 53.3e-6 * seq - 8.7e-6;
        break;
      }
    }
  }

  void unpack(const uint8_t* pkt, double stamp_s) {
    const bool dual = pkt[1204] == 0x39;
    const bool nebula = rules_ == Rules::kNebula;
    const bool vls = s_.model == VelodyneModel::kVLS128, vlp16 = s_.model == VelodyneModel::kVLP16;
    const std::size_t blocks = vls && dual ? 8 : 12;
    // Manual: the rate over one block step (its next firing sequence), the last sequence reusing it.
    const std::size_t step = vls ? (dual ? 0 : 4) : (dual ? 2 : 1);
    float last_diff = 0;
    uint16_t az_next = 0;
    for (std::size_t b = 0; b < blocks; ++b) {
      const uint8_t* blk = pkt + 100 * b;
      const uint16_t id = u16(blk), rot = u16(blk + 2);
      int bank = 0;
      if (vls) {
        bank = id == 0xEEFF ? 0 : id == 0xDDFF ? 1 : id == 0xCCFF ? 2 : id == 0xBBFF ? 3 : -1;
      } else {
        bank = id == 0xEEFF ? 0 : -1;
      }
      if (bank < 0) return;
      // Block azimuth and the difference the interpolation spreads over one firing sequence.
      uint16_t az = rot;
      double diff = 0;
      if (nebula) {  // N1, N2
        az = b == 0 ? rot : az_next;
        const std::size_t d = dual ? 1 : 0;
        float fd;
        if (b < 12 - (1 + d)) {
          az_next = u16(pkt + 100 * (b + 1 + d) + 2);
          fd = static_cast<float>((36000 + az_next - az) % 36000);
          last_diff = fd;
        } else if (vlp16) {
          fd = b == 12 - d - 1 ? 0.0f : last_diff;
        } else {
          fd = b == 12 - 4 * d - 1 ? 0.0f : last_diff;
        }
        diff = fd;
      } else if (step > 0) {
        // The difference over one sequence; the last sequence reuses the one before. A difference
        // faster than 1667 rpm (a sensor sending only a sector jumps across the rest) is not a
        // rotation: the previous plausible one stands in.
        const double period_us = vls ? 53.3 : vlp16 ? 110.592 : 55.296;
        auto diff_at = [&](std::size_t base) {
          return static_cast<double>((36000 + u16(pkt + 100 * (base + step) + 2) - u16(pkt + 100 * base + 2)) % 36000);
        };
        std::size_t base = b - b % step;
        if (base + step >= blocks) base -= step;
        diff = diff_at(base);
        while (!(diff > 0 && diff / period_us <= 1.0) && base >= step) {
          base -= step;
          diff = diff_at(base);
        }
      } else {
        diff = 0.36 * 53.3;  // VLS-128 dual: one sequence per packet; our decoder's nominal 600 rpm
      }
      // N4: VLP-16 and VLS-128 also check the block's (interpolation base) azimuth; VLP-32C below.
      const bool vlp32 = s_.model == VelodyneModel::kVLP32C;
      if (nebula && !vlp32 && s_.min_angle < s_.max_angle && !(az >= s_.min_angle * 100 && az <= s_.max_angle * 100))
        continue;
      for (std::size_t j = 0; j < 32; ++j) {
        const uint8_t* c = blk + 4 + 3 * j;
        const uint16_t raw = u16(c);
        const uint8_t* o = pkt + 100 * (b % 2 == 1 ? b - 1 : b + 1) + 4 + 3 * j;
        const uint16_t other = dual ? u16(o) : 0;
        if (scan_ts_ < 0) {
          scan_ts_ = stamp_s;
          scan_ns_ = stamp_ns_;
        }
        if (raw == 0 || (dual && b % 2 == 1 && other == raw)) continue;
        const int laser = vlp16 ? static_cast<int>(j % 16) : bank * 32 + static_cast<int>(j);
        const auto& l = cal_.lasers[static_cast<std::size_t>(laser)];
        const float res = vls ? 0.004f : static_cast<float>(cal_.distance_resolution);
        float dist = static_cast<float>(raw) * res;
        dist += static_cast<float>(l.dist_correction);
        if (!(dist > s_.min_range && dist < s_.max_range)) continue;
        if (nebula && s_.model == VelodyneModel::kVLP32C) {  // N4: the raw block azimuth only
          const bool in = (rot >= s_.min_angle * 100 && rot <= s_.max_angle * 100 && s_.min_angle < s_.max_angle) ||
                          (s_.min_angle > s_.max_angle && (rot <= s_.max_angle * 100 || rot >= s_.min_angle * 100));
          if (!in) continue;
        }
        double t = 0, tb = 0;
        // nebula's timing tables follow the configured return mode (the VLS-128's none), ours the packet's.
        timing(b, j, laser, nebula ? (vls ? false : s_.dual_config) : dual, t, tb);
        long azc = 0;
        // nebula keeps the corrections in single precision.
        const double rot_h =
            (nebula ? static_cast<double>(static_cast<float>(l.rot_correction)) : l.rot_correction) * 180.0 / kPi * 100;
        if (nebula) {  // N3, N5: single precision as nebula computes it
          float f = 0;
          if (vlp16) {
            const auto fi = static_cast<float>(j / 16), dsr = static_cast<float>(j % 16);
            f = static_cast<float>(az + (static_cast<float>(diff) * ((dsr * 2.304f) + (fi * 55.296f)) / 110.592f) -
                                   rot_h);
          } else if (vls) {
            const int g = laser / 8;
            const float cache = (2.665f / 53.3f) * static_cast<float>(g + g / 8);
            f = static_cast<float>(az + (static_cast<float>(diff) * cache) - rot_h);
          } else {
            f = static_cast<float>(az + (static_cast<float>(diff) * 2.304f / 55.296f * static_cast<float>(j)) - rot_h);
          }
          if (f < 0) f = static_cast<float>(f + 36000.0);
          azc = static_cast<long>(static_cast<uint16_t>(std::round(f))) % 36000;
        } else {
          const double period = vls ? 53.3e-6 : 55.296e-6 * (vlp16 ? 2 : 1);
          azc = std::lround(az + diff * (t - tb) / period - rot_h + 1e-6) % 36000;  // exact halves round up
          if (azc < 0) azc += 36000;
        }
        if (!(nebula && s_.model == VelodyneModel::kVLP32C) && !in_sector(azc)) continue;
        const double a = static_cast<double>(azc) * 0.01 * kPi / 180, e = l.vert_correction;
        RefPoint p;
        p.x = static_cast<float>(dist * std::cos(e) * std::cos(a));
        p.y = static_cast<float>(-dist * std::cos(e) * std::sin(a));
        p.z = static_cast<float>(dist * std::sin(e));
        p.intensity = c[2];
        p.channel = static_cast<uint16_t>(l.ring);
        p.azimuth =
            static_cast<float>(nebula && s_.model == VelodyneModel::kVLP32C ? rot * 0.01 * kPi / 180 : a);  // N7
        if (!dual) {
          p.return_type = pkt[1204] == 0x38 ? 1 : 3;
        } else if (other == 0 || other == raw) {
          p.return_type = 6;
        } else {
          const uint8_t oi = o[2];
          bool first = nebula && vlp16 ? raw > other : raw < other;  // N6
          bool strongest = c[2] > oi;
          if (c[2] == oi) strongest = nebula ? !first : b % 2 == 1;
          p.return_type = first ? (strongest ? 9 : 4) : (strongest ? 10 : 5);
        }
        if (nebula) {  // N9, with nebula's timing table arithmetic
          const double cycle = (vls ? 53.3 : 55.296) * 1e-6, firing = (vls ? 2.665 : 2.304) * 1e-6;
          double offset = 0;
          if (vlp16) {
            const auto x = static_cast<double>(b);
            const double block_index = s_.dual_config ? (x - static_cast<double>(b % 2)) + static_cast<double>(j / 16)
                                                      : (x * 2) + static_cast<double>(j / 16);
            offset = cycle * block_index + firing * static_cast<double>(j % 16);
          } else if (vls) {
            const int g = laser / 8;
            offset = cycle * static_cast<double>(b / 4) + firing * static_cast<double>(g + laser / 64) - 8.7 * 1e-6;
          } else {
            offset = cycle * static_cast<double>(s_.dual_config ? b / 2 : b) + firing * static_cast<double>(j / 2);
          }
          double ts = stamp_s - scan_ts_ + static_cast<float>(offset);  // its table holds floats
          if (ts < 0) ts = 0;
          p.time_ns = static_cast<uint32_t>(ts * 1e9);
        } else {
          p.time_ns = stamp_ns_ - scan_ns_ + std::llround(t * 1e9);
        }
        last_block_ts_ = stamp_s;
        last_block_ns_ = stamp_ns_;
        scan_.push_back(p);
      }
    }
  }

  const VelodyneCalibration& cal_;
  FixtureSettings s_;
  Rules rules_;
  std::vector<RefPoint> scan_, overflow_;
  double scan_ts_ = -1, last_block_ts_ = 0;
  int64_t stamp_ns_ = 0, scan_ns_ = 0, last_block_ns_ = 0;
  uint32_t prev_first_ = 0;
  std::size_t processed_ = 0;
  bool has_scanned_ = false;
};

struct Fixture {
  std::string model_dir, calibration, reference;
  FixtureSettings settings;
};

// The settings nebula's test used (NOTES.txt).
Fixture fixture(const std::string& name) {
  Fixture f;
  if (name == "vlp16") {
    f = {"vlp16/1673400471837873222", "VLP16.yaml", "vlp16/1673400472138016708.pcd", {}};
    // The reference's time fields follow the single-return timing table (N10).
    f.settings = {VelodyneModel::kVLP16, 0.3, 300, 0, 359, 0, false};
  } else if (name == "vlp32") {
    f = {"vlp32/1713492677464078412", "VLP32.yaml", "vlp32/1713492677464078412.pcd", {}};
    f.settings = {VelodyneModel::kVLP32C, 0.4, 50, 270, 90, 180, false};
  } else {
    f = {"vls128/1614315746471294674", "VLS128.yaml", "vls128/1585897255376374245.pcd", {}};
    f.settings = {VelodyneModel::kVLS128, 0.3, 300, 0, 359, 0, true};
  }
  return f;
}

int64_t reference_bag_ns(const Fixture& f) { return std::stoll(std::filesystem::path(f.reference).stem().string()); }

struct Clouds {
  std::vector<VelodynePoint> ours;
  int64_t ours_stamp_ns = 0;
  std::vector<RefPoint> manual, nebula, reference;
};

// Runs our assembler and both rule sets over a fixture the way nebula's test does (every packet of every
// message, in order) and keeps the first cloud completed while the reference message is processed.
// nebula's test passes each packet's stamp in whole seconds (N11), which the reference's time fields
// show: times restart at each packet, and carried points' times are re-based in double seconds.
Clouds run_fixture(const Fixture& f, const std::vector<RawPacket>& packets) {
  Clouds out;
  const auto dir = data_dir();
  const VelodyneCalibration cal = read_velodyne_calibration(dir / "calibration" / f.calibration, f.settings.model);
  VelodyneDecoderOptions o;
  o.model = f.settings.model;
  o.min_range = f.settings.min_range;
  o.max_range = f.settings.max_range;
  o.sector_min_deg = f.settings.min_angle;
  o.sector_max_deg = f.settings.max_angle;
  VelodyneSweepOptions so;
  so.scan_phase_deg = f.settings.phase_deg;
  so.max_gap_ns = 1'000'000'000;  // the VLP-32C bag holds a 180 deg sector: 50 ms without packets
  VelodyneSweepAssembler assembler(cal, o, so);
  RuleDecoder manual(cal, f.settings, Rules::kManual), nebula(cal, f.settings, Rules::kNebula);
  const int64_t target = reference_bag_ns(f);
  bool got_ours = false, got_manual = false, got_nebula = false;
  for (const auto& p : packets) {
    const int64_t stamp_ns = static_cast<int64_t>(p.sec) * 1000000000 + p.nanosec;
    assembler.add_packet(p.data, stamp_ns);
    while (assembler.has_sweep()) {
      VelodyneSweep s = assembler.take();
      if (p.bag_ns == target && !got_ours) {
        out.ours = std::move(s.points);
        out.ours_stamp_ns = s.stamp_ns;
        got_ours = true;
      }
    }
    std::vector<RefPoint> cloud;
    if (manual.feed(p.data.data(), stamp_ns, cloud) && p.bag_ns == target && !got_manual) {
      out.manual = cloud;
      got_manual = true;
    }
    if (nebula.feed(p.data.data(), static_cast<int64_t>(p.sec) * 1000000000, cloud) && p.bag_ns == target &&
        !got_nebula) {
      out.nebula = cloud;
      got_nebula = true;
    }
  }
  out.reference = read_reference_pcd(dir / f.reference);
  EXPECT_EQ(assembler.stats().malformed + assembler.stats().truncated + assembler.stats().out_of_order, 0u);
  return out;
}

double dist3(float ax, float ay, float az, float bx, float by, float bz) {
  return std::sqrt(double(ax - bx) * double(ax - bx) + double(ay - by) * double(ay - by) +
                   double(az - bz) * double(az - bz));
}

// Two clouds agree point by point (same order) within 1 mm. A point further off must be an azimuth
// rounding tie: 0.01 deg away at its range (both sides round x.5 hundredths; which way depends on the
// last bit of the arithmetic). Returns how many such ties there were.
template <class A, class B>
int expect_same_cloud(const std::vector<A>& a, const std::vector<B>& b, const char* what) {
  EXPECT_EQ(a.size(), b.size()) << what;
  int ties = 0, failures = 0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    const double d = dist3(a[i].x, a[i].y, a[i].z, b[i].x, b[i].y, b[i].z);
    if (d <= 1e-3) continue;
    const double r = std::hypot(double(a[i].x), double(a[i].y));
    const double tie = r * 0.01 * kPi / 180;  // one azimuth step at this range
    if (std::abs(d - tie) < 1e-3 && std::abs(a[i].z - b[i].z) < 1e-3) {
      ++ties;
      continue;
    }
    if (++failures <= 5) {
      ADD_FAILURE() << what << ": point " << i << " differs by " << d << " m: (" << a[i].x << ", " << a[i].y << ", "
                    << a[i].z << ") vs (" << b[i].x << ", " << b[i].y << ", " << b[i].z << ")";
    }
  }
  EXPECT_EQ(failures, 0) << what;
  return ties;
}

class VelodyneFixtureTest : public ::testing::TestWithParam<std::string> {};

TEST_P(VelodyneFixtureTest, ReproducesReferenceSweep) {
  const Fixture f = fixture(GetParam());
  const auto dir = data_dir();
  if (!std::filesystem::exists(dir / f.model_dir))
    GTEST_SKIP() << "no Velodyne fixtures in " << dir << " (set CDC_DATA_DIR)";
  const std::vector<RawPacket> packets = read_packets(dir / f.model_dir);
  ASSERT_FALSE(packets.empty());
  const Clouds c = run_fixture(f, packets);
  ASSERT_FALSE(c.reference.empty()) << "reference " << f.reference << " unreadable";
  ASSERT_FALSE(c.ours.empty()) << "no sweep completed in the reference message";

  // 1. Ours against the manuals' formulas, point for point.
  const int ties_ours = expect_same_cloud(c.ours, c.manual, "ours vs manual formulas");
  for (std::size_t i = 0; i < std::min(c.ours.size(), c.manual.size()); ++i) {
    const auto& p = c.ours[i];
    const auto& q = c.manual[i];
    ASSERT_EQ(p.ring, q.channel) << i;
    ASSERT_EQ(p.intensity, q.intensity) << i;
    ASSERT_EQ(nebula_type(p.return_type), q.return_type) << i;
    ASSERT_EQ(p.time_ns - c.ours_stamp_ns, q.time_ns) << i << " block " << int(p.block) << " laser " << p.laser_id
                                                      << " t " << p.time_ns << " stamp " << c.ours_stamp_ns;
  }
  // 2. nebula's rules against nebula's cloud.
  const int ties_ref = expect_same_cloud(c.nebula, c.reference, "nebula rules vs reference");
  const bool full = GetParam() == "vlp16";  // the only reference with all fields
  if (full) {
    for (std::size_t i = 0; i < std::min(c.nebula.size(), c.reference.size()); ++i) {
      const auto& p = c.nebula[i];
      const auto& q = c.reference[i];
      ASSERT_EQ(p.intensity, q.intensity) << i;
      ASSERT_EQ(p.channel, q.channel) << i;
      ASSERT_EQ(p.return_type, q.return_type) << i;
      ASSERT_NEAR(p.azimuth, q.azimuth, 1e-6) << i;
      ASSERT_EQ(p.time_ns, q.time_ns) << i;
    }
  }
  // How much of the reference our sweep reproduces (informative; the rules above account for the rest):
  // reference points with one of ours within 1 mm.
  std::map<std::array<long, 3>, std::vector<std::size_t>> grid;
  auto cell = [](float v) { return static_cast<long>(std::floor(v / 0.01f)); };
  for (std::size_t i = 0; i < c.ours.size(); ++i)
    grid[{cell(c.ours[i].x), cell(c.ours[i].y), cell(c.ours[i].z)}].push_back(i);
  std::size_t within = 0;
  for (const auto& q : c.reference) {
    bool hit = false;
    for (long dx = -1; dx <= 1 && !hit; ++dx) {
      for (long dy = -1; dy <= 1 && !hit; ++dy) {
        for (long dz = -1; dz <= 1 && !hit; ++dz) {
          const auto it = grid.find({cell(q.x) + dx, cell(q.y) + dy, cell(q.z) + dz});
          if (it == grid.end()) continue;
          for (const std::size_t i : it->second)
            hit = hit || dist3(c.ours[i].x, c.ours[i].y, c.ours[i].z, q.x, q.y, q.z) <= 1e-3;
        }
      }
    }
    within += hit;
  }
  std::printf(
      "[ %s ] ours %zu points, reference %zu; nebula's rules reproduce the reference (%d rounding ties), ours "
      "the manual formulas (%d ties); reference points with one of ours within 1 mm: %zu (%.1f %%)\n",
      GetParam().c_str(), c.ours.size(), c.reference.size(), ties_ref, ties_ours, within,
      100.0 * static_cast<double>(within) / static_cast<double>(c.reference.size()));
  // Rounding ties are rare: a handful per sweep.
  EXPECT_LT(ties_ours, 20);
  EXPECT_LT(ties_ref, 20);
}

INSTANTIATE_TEST_SUITE_P(Fixtures, VelodyneFixtureTest, ::testing::Values("vlp16", "vlp32", "vls128"));

TEST(VelodyneFixture, PacketHeadersAndModels) {
  const auto dir = data_dir();
  if (!std::filesystem::exists(dir / "vlp16"))
    GTEST_SKIP() << "no Velodyne fixtures in " << dir << " (set CDC_DATA_DIR)";
  const std::vector<std::pair<std::string, VelodyneModel>> cases = {
      {"vlp16", VelodyneModel::kVLP16}, {"vlp32", VelodyneModel::kVLP32C}, {"vls128", VelodyneModel::kVLS128}};
  for (const auto& [name, model] : cases) {
    const auto packets = read_packets(dir / fixture(name).model_dir);
    ASSERT_FALSE(packets.empty());
    const auto h = read_velodyne_packet_header(packets[0].data);
    ASSERT_TRUE(h);
    EXPECT_EQ(velodyne_model_from_product_id(h->product_id), model) << name;
    EXPECT_LT(h->gps_time_us, 3600u * 1000000u) << name;
    // The model comes from the packet when not configured.
    VelodyneDecoder d(read_velodyne_calibration(dir / "calibration" / fixture(name).calibration), {});
    std::vector<VelodynePoint> pts;
    EXPECT_EQ(d.decode(packets[0].data, 0, pts), VelodynePacketStatus::kOk);
    EXPECT_EQ(d.model(), model);
    EXPECT_FALSE(pts.empty());
  }
}

// ---------------------------------------------------------------------------------------------
// Calibration

TEST(VelodyneCalibration, BuiltInTablesMatchTheFixtureFiles) {
  const auto dir = data_dir() / "calibration";
  if (!std::filesystem::exists(dir)) GTEST_SKIP() << "no calibration files in " << dir << " (set CDC_DATA_DIR)";
  const std::vector<std::pair<std::string, VelodyneModel>> cases = {{"VLP16.yaml", VelodyneModel::kVLP16},
                                                                    {"VLP32.yaml", VelodyneModel::kVLP32C},
                                                                    {"VLS128.yaml", VelodyneModel::kVLS128}};
  for (const auto& [file, model] : cases) {
    const VelodyneCalibration read = read_velodyne_calibration(dir / file, model);
    const VelodyneCalibration builtin = default_velodyne_calibration(model);
    ASSERT_EQ(read.lasers.size(), builtin.lasers.size()) << file;
    for (std::size_t i = 0; i < read.lasers.size(); ++i) {
      EXPECT_NEAR(read.lasers[i].vert_correction, builtin.lasers[i].vert_correction, 1e-4) << file << " laser " << i;
      EXPECT_NEAR(read.lasers[i].rot_correction, builtin.lasers[i].rot_correction, 1e-4) << file << " laser " << i;
      EXPECT_EQ(read.lasers[i].ring, builtin.lasers[i].ring) << file << " laser " << i;
    }
  }
  // VLP-16 rings interleave: laser 0 (-15 deg) is ring 0, laser 1 (+1 deg) ring 8, laser 15 (+15) ring 15.
  const auto vlp16 = read_velodyne_calibration(dir / "VLP16.yaml");
  EXPECT_EQ(vlp16.lasers[0].ring, 0);
  EXPECT_EQ(vlp16.lasers[1].ring, 8);
  EXPECT_EQ(vlp16.lasers[15].ring, 15);
}

class TempDir {
 public:
  TempDir() {
    path_ = std::filesystem::temp_directory_path() /
            ("cdc_velodyne_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) + "_" +
             std::to_string(reinterpret_cast<uintptr_t>(this)));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  const std::filesystem::path& dir() const { return path_; }
  std::filesystem::path file(const std::string& name, const std::string& text) const {
    std::ofstream(path_ / name) << text;
    return path_ / name;
  }

 private:
  std::filesystem::path path_;
};

std::string calibration_yaml(int n, const std::string& drop_key = "", int drop_at = -1) {
  std::ostringstream s;
  s << "num_lasers: " << n << "\ndistance_resolution: 0.002\nlasers:\n";
  for (int i = 0; i < n; ++i) {
    s << "  - {";
    std::vector<std::pair<std::string, std::string>> kv = {{"laser_id", std::to_string(i)},
                                                           {"rot_correction", "0.0"},
                                                           {"vert_correction", std::to_string(0.01 * i - 0.1)},
                                                           {"dist_correction", "0.0"}};
    bool first = true;
    for (const auto& [k, v] : kv) {
      if (i == drop_at && k == drop_key) continue;
      s << (first ? "" : ", ") << k << ": " << v;
      first = false;
    }
    s << "}\n";
  }
  return s.str();
}

TEST(VelodyneCalibration, BadFilesNameTheFileAndTheEntry) {
  TempDir t;
  auto message = [](const std::filesystem::path& p, std::optional<VelodyneModel> m = std::nullopt) -> std::string {
    try {
      read_velodyne_calibration(p, m);
    } catch (const FormatError& e) {
      return e.what();
    }
    return "no error";
  };
  const auto ok = t.file("ok.yaml", calibration_yaml(16));
  EXPECT_EQ(read_velodyne_calibration(ok, VelodyneModel::kVLP16).lasers.size(), 16u);
  const auto missing = t.file("missing.yaml", calibration_yaml(16, "vert_correction", 5));
  std::string m = message(missing);
  EXPECT_NE(m.find("missing.yaml"), std::string::npos) << m;
  EXPECT_NE(m.find("lasers[5]"), std::string::npos) << m;
  EXPECT_NE(m.find("vert_correction"), std::string::npos) << m;
  m = message(ok, VelodyneModel::kVLP32C);
  EXPECT_NE(m.find("ok.yaml"), std::string::npos) << m;
  EXPECT_NE(m.find("16 lasers"), std::string::npos) << m;
  std::string text = calibration_yaml(16);
  text.replace(text.find("num_lasers: 16"), 14, "num_lasers: 17");
  m = message(t.file("count.yaml", text));
  EXPECT_NE(m.find("count.yaml"), std::string::npos) << m;
  EXPECT_NE(m.find("17"), std::string::npos) << m;
  text = calibration_yaml(16);
  text.replace(text.find("laser_id: 3,"), 12, "laser_id: 2,");
  m = message(t.file("dup.yaml", text));
  EXPECT_NE(m.find("lasers[3]"), std::string::npos) << m;
  EXPECT_NE(m.find("twice"), std::string::npos) << m;
  text = calibration_yaml(16);
  text.replace(text.find("dist_correction: 0.0"), 20, "dist_correction: abc");
  m = message(t.file("nan.yaml", text));
  EXPECT_NE(m.find("lasers[0]"), std::string::npos) << m;
  EXPECT_NE(m.find("not a number"), std::string::npos) << m;
  m = message(t.file("broken.yaml", "lasers: [ {"));
  EXPECT_NE(m.find("broken.yaml"), std::string::npos) << m;
  m = message(t.dir() / "absent.yaml");
  EXPECT_NE(m.find("absent.yaml"), std::string::npos) << m;
  text = calibration_yaml(16);
  text.replace(text.find("dist_correction: 0.0"), 20, "dist_correction: .nan");
  m = message(t.file("notfinite.yaml", text));
  EXPECT_NE(m.find("notfinite.yaml: lasers[0]: 'dist_correction' is not a finite number"), std::string::npos) << m;
}

// ---------------------------------------------------------------------------------------------
// Synthetic packets from the manuals' tables (HDL-32E, HDL-64E)

struct Block {
  uint16_t id = 0xEEFF;
  uint16_t azimuth = 0;                 // [0.01 deg]
  std::array<uint16_t, 32> distance{};  // raw units
  std::array<uint8_t, 32> intensity{};
};

std::vector<uint8_t> make_packet(const std::array<Block, 12>& blocks, uint8_t mode, uint8_t product, uint32_t gps_us) {
  std::vector<uint8_t> p(kVelodynePacketSize, 0);
  for (std::size_t b = 0; b < 12; ++b) {
    uint8_t* q = p.data() + 100 * b;
    q[0] = static_cast<uint8_t>(blocks[b].id & 0xFF);
    q[1] = static_cast<uint8_t>(blocks[b].id >> 8);
    q[2] = static_cast<uint8_t>(blocks[b].azimuth & 0xFF);
    q[3] = static_cast<uint8_t>(blocks[b].azimuth >> 8);
    for (std::size_t c = 0; c < 32; ++c) {
      q[4 + 3 * c] = static_cast<uint8_t>(blocks[b].distance[c] & 0xFF);
      q[5 + 3 * c] = static_cast<uint8_t>(blocks[b].distance[c] >> 8);
      q[6 + 3 * c] = blocks[b].intensity[c];
    }
  }
  for (int i = 0; i < 4; ++i) p[1200 + static_cast<std::size_t>(i)] = static_cast<uint8_t>(gps_us >> (8 * i));
  p[1204] = mode;
  p[1205] = product;
  return p;
}

// Expected point from the manual's formulas: azimuth rounded to 0.01 deg, x = d cos(e) cos(a),
// y = -d cos(e) sin(a), z = d sin(e).
void expect_point(const VelodynePoint& p, double distance, double elevation_deg, double azimuth_h,
                  const std::string& what) {
  const long az = std::lround(azimuth_h) % 36000;
  const double a = static_cast<double>(az) * 0.01 * kPi / 180, e = elevation_deg * kPi / 180;
  EXPECT_NEAR(p.distance, distance, 1e-5) << what;
  EXPECT_NEAR(p.x, distance * std::cos(e) * std::cos(a), 1e-4) << what;
  EXPECT_NEAR(p.y, -distance * std::cos(e) * std::sin(a), 1e-4) << what;
  EXPECT_NEAR(p.z, distance * std::sin(e), 1e-4) << what;
  EXPECT_NEAR(p.azimuth, a, 1e-6) << what;
}

TEST(VelodyneSynthetic, Hdl32eGeometryAndTiming) {
  // HDL-32E manual: 12 blocks of the 32 lasers per packet, one block per 46.08 us firing cycle,
  // lasers 1.152 us apart; elevation table -30.67 .. +10.67 deg.
  const double elevation[32] = {-30.67, -9.33,  -29.33, -8.00,  -28.00, -6.67,  -26.67, -5.33,  -25.33, -4.00,  -24.00,
                                -2.67,  -22.67, -1.33,  -21.33, 0.00,   -20.00, 1.33,   -18.67, 2.67,   -17.33, 4.00,
                                -16.00, 5.33,   -14.67, 6.67,   -13.33, 8.00,   -12.00, 9.33,   -10.67, 10.67};
  std::array<Block, 12> blocks;
  const int step = 16;  // [0.01 deg] per block (about 580 rpm; 17 would make x.5 rounding ties)
  for (std::size_t b = 0; b < 12; ++b) {
    blocks[b].azimuth = static_cast<uint16_t>((35950 + static_cast<int>(b) * step) % 36000);  // wraps through 0
    for (std::size_t c = 0; c < 32; ++c) {
      blocks[b].distance[c] = static_cast<uint16_t>(2500 + 100 * c + b);  // 5 m + ...
      blocks[b].intensity[c] = static_cast<uint8_t>(c + b);
    }
  }
  blocks[3].distance[7] = 0;  // no return
  const auto pkt = make_packet(blocks, 0x37, 0x21, 123456);
  VelodyneDecoderOptions o;
  o.min_range = 0.1;
  VelodyneDecoder d(default_velodyne_calibration(VelodyneModel::kHDL32E), o);
  std::vector<VelodynePoint> pts;
  const int64_t stamp = 5'000'000'000;
  ASSERT_EQ(d.decode(pkt, stamp, pts), VelodynePacketStatus::kOk);
  EXPECT_EQ(d.model(), VelodyneModel::kHDL32E);
  ASSERT_EQ(pts.size(), 12u * 32u - 1u);
  std::size_t k = 0;
  for (std::size_t b = 0; b < 12; ++b) {
    for (std::size_t c = 0; c < 32; ++c) {
      if (b == 3 && c == 7) continue;
      const VelodynePoint& p = pts[k++];
      const std::string what = "block " + std::to_string(b) + " laser " + std::to_string(c);
      const double t_us = 46.08 * static_cast<double>(b) + 1.152 * static_cast<double>(c);
      EXPECT_EQ(p.time_ns, stamp + std::llround(t_us * 1000)) << what;
      EXPECT_EQ(p.laser_id, c);
      EXPECT_EQ(p.block, b);
      EXPECT_EQ(p.intensity, static_cast<float>(c + b));
      EXPECT_EQ(p.return_type, VelodyneReturnType::kStrongest);
      // Azimuth: the block's plus the rotation during the laser's delay (the next block 46.08 us on).
      const double az = 35950.0 + static_cast<double>(b * step) + step * (1.152 * static_cast<double>(c) / 46.08);
      expect_point(p, 0.002 * static_cast<double>(2500 + 100 * c + b), elevation[c], az, what);
    }
  }
  // Ring: by elevation, laser 0 (-30.67) lowest, laser 31 (+10.67) highest.
  EXPECT_EQ(pts[0].ring, 0);
  EXPECT_EQ(pts[31].ring, 31);
  EXPECT_EQ(read_velodyne_packet_header(pkt)->gps_time_us, 123456u);
}

TEST(VelodyneSynthetic, Hdl32eDualReturn) {
  // Dual return: blocks 2k (last) and 2k+1 (strongest) hold the two returns of one firing.
  std::array<Block, 12> blocks;
  for (std::size_t b = 0; b < 12; ++b) {
    blocks[b].azimuth = static_cast<uint16_t>(1000 + 34 * static_cast<int>(b / 2));
    for (std::size_t c = 0; c < 32; ++c) {
      blocks[b].distance[c] = 5000;  // same: one point
      blocks[b].intensity[c] = 50;
    }
  }
  blocks[0].distance[0] = 6000;  // last return farther, weaker
  blocks[0].intensity[0] = 10;
  blocks[1].distance[0] = 5000;
  blocks[1].intensity[0] = 90;
  const auto pkt = make_packet(blocks, 0x39, 0x21, 0);
  VelodyneDecoder d(default_velodyne_calibration(VelodyneModel::kHDL32E), {});
  std::vector<VelodynePoint> pts;
  ASSERT_EQ(d.decode(pkt, 0, pts), VelodynePacketStatus::kOk);
  ASSERT_EQ(pts.size(), 6u * 32u + 1u);  // duplicates dropped, one extra for the two-return firing
  EXPECT_EQ(pts[0].return_type, VelodyneReturnType::kDualLastWeak);
  EXPECT_NEAR(pts[0].distance, 12.0, 1e-6);
  EXPECT_EQ(pts[1].return_type, VelodyneReturnType::kDualOnly);
  // The strongest (block 1) comes after block 0's 32 points.
  EXPECT_EQ(pts[32].block, 1);
  EXPECT_EQ(pts[32].return_type, VelodyneReturnType::kDualFirstStrongest);
  EXPECT_NEAR(pts[32].distance, 10.0, 1e-6);
  // Both returns share the firing time; pairs are 46.08 us apart.
  EXPECT_EQ(pts[0].time_ns, pts[32].time_ns);
  EXPECT_EQ(pts[33].time_ns, std::llround(46.08 * 1000));
  // Block 1's point uses the pair's azimuth, interpolated towards the next pair (34 per 46.08 us).
  EXPECT_NEAR(pts[32].azimuth, 1000 * 0.01 * kPi / 180, 1e-6);
}

// The HDL-64E S2 manual's laser firing time table, within a firing of a block pair [us]: 8 groups of 4
// lasers, a group every 6 us, the lasers of a group 0, 1.26, 2.46 and 3.66 us after its start.
constexpr double kHdl64S2Cycle = 48.0;
constexpr double kHdl64S2Offset[32] = {0,     1.26,  2.46,  3.66,  6,     7.26,  8.46,  9.66,  12,    13.26, 14.46,
                                       15.66, 18,    19.26, 20.46, 21.66, 24,    25.26, 26.46, 27.66, 30,    31.26,
                                       32.46, 33.66, 36,    37.26, 38.46, 39.66, 42,    43.26, 44.46, 45.66};

TEST(VelodyneSynthetic, Hdl64eBanksTimingAndCalibrationModel) {
  // HDL-64E S2: blocks alternate upper (0xEEFF, lasers 0-31) and lower (0xDDFF, lasers 32-63); an upper
  // and a lower laser fire together, one firing of both blocks every 48 us (kHdl64S2Offset).
  VelodyneCalibration cal = default_velodyne_calibration(VelodyneModel::kHDL64E);
  // A laser with the full calibration model: origin offsets, two-point distance correction, intensity.
  auto& l = cal.lasers[40];
  l.rot_correction = -0.05;
  l.dist_correction = 1.2;
  l.two_pt_correction = true;
  l.dist_correction_x = 1.25;
  l.dist_correction_y = 1.18;
  l.vert_offset_correction = 0.2;
  l.horiz_offset_correction = 0.026;
  l.focal_distance = 1500;
  l.focal_slope = 1.2;
  std::array<Block, 12> blocks;
  for (std::size_t b = 0; b < 12; ++b) {
    blocks[b].id = b % 2 == 0 ? 0xEEFF : 0xDDFF;
    blocks[b].azimuth = static_cast<uint16_t>(9000 + 16 * static_cast<int>(b / 2));
    for (std::size_t c = 0; c < 32; ++c) {
      blocks[b].distance[c] = static_cast<uint16_t>(10000 + 37 * c);  // 20 m + ...
      blocks[b].intensity[c] = 100;
    }
  }
  const auto pkt = make_packet(blocks, 0, 0, 0);  // no product id: configured
  VelodyneDecoderOptions o;
  o.model = VelodyneModel::kHDL64E;
  VelodyneDecoder d(cal, o);
  std::vector<VelodynePoint> pts;
  ASSERT_EQ(d.decode(pkt, 0, pts), VelodynePacketStatus::kOk);
  ASSERT_EQ(pts.size(), 384u);
  const double cycle = kHdl64S2Cycle;
  for (std::size_t b = 0; b < 12; ++b) {
    for (std::size_t c = 0; c < 32; ++c) {
      const VelodynePoint& p = pts[b * 32 + c];
      const auto laser = static_cast<std::size_t>(b % 2 == 0 ? c : 32 + c);
      const std::string what = "block " + std::to_string(b) + " channel " + std::to_string(c);
      ASSERT_EQ(p.laser_id, laser) << what;
      const double t_us = cycle * static_cast<double>(b / 2) + kHdl64S2Offset[c];
      EXPECT_EQ(p.time_ns, std::llround(t_us * 1000)) << what;
      // Rotation between sequences: 16 per 48 us; the last sequence reuses it.
      const double az = 9000.0 + 16.0 * static_cast<double>(b / 2) + 16.0 * (kHdl64S2Offset[c] / cycle) -
                        cal.lasers[laser].rot_correction * 180 / kPi * 100;
      const double raw_m = 0.002 * static_cast<double>(10000 + 37 * c);
      if (laser != 40) {
        expect_point(p, raw_m, cal.lasers[laser].vert_correction * 180 / kPi, az, what);
        EXPECT_EQ(p.intensity, 100.0f);
        continue;
      }
      // The HDL-64E manual's model, in the sensor's frame (x right, y forward), then x forward, y left.
      const double d0 = raw_m + l.dist_correction;
      const double a = static_cast<double>(std::lround(az) % 36000) * 0.01 * kPi / 180;
      const double cv = std::cos(l.vert_correction), sv = std::sin(l.vert_correction);
      const double xy = d0 * cv - l.vert_offset_correction * sv;
      const double xx = std::abs(xy * std::sin(a) - l.horiz_offset_correction * std::cos(a));
      const double yy = std::abs(xy * std::cos(a) + l.horiz_offset_correction * std::sin(a));
      const double cx = (l.dist_correction - l.dist_correction_x) * (xx - 2.4) / (25.04 - 2.4) + l.dist_correction_x;
      const double cy = (l.dist_correction - l.dist_correction_y) * (yy - 1.93) / (25.04 - 1.93) + l.dist_correction_y;
      const double dx = raw_m + cx, dy = raw_m + cy;
      const double sx =
          (dx * cv - l.vert_offset_correction * sv) * std::sin(a) - l.horiz_offset_correction * std::cos(a);
      const double sy =
          (dy * cv - l.vert_offset_correction * sv) * std::cos(a) + l.horiz_offset_correction * std::sin(a);
      const double sz = dy * sv + l.vert_offset_correction * cv;
      EXPECT_NEAR(p.x, sy, 1e-4) << what;
      EXPECT_NEAR(p.y, -sx, 1e-4) << what;
      EXPECT_NEAR(p.z, sz, 1e-4) << what;
      const double focal = 1 - l.focal_distance / 13100, near = 1 - static_cast<double>(10000 + 37 * c) / 65535;
      const double intensity = std::min(255.0, 100 + l.focal_slope * std::abs(256 * focal * focal - 256 * near * near));
      EXPECT_NEAR(p.intensity, intensity, 1e-3) << what;
    }
  }
  // A block id the HDL-64E does not send.
  auto bad = pkt;
  bad[500] = 0x12;
  pts.clear();
  EXPECT_EQ(d.decode(bad, 0, pts), VelodynePacketStatus::kMalformed);
  EXPECT_TRUE(pts.empty());
}

// The point of `laser` decoded from `block`, or nullptr.
const VelodynePoint* find_point(const std::vector<VelodynePoint>& pts, std::size_t block, std::size_t laser) {
  for (const auto& p : pts) {
    if (p.block == block && p.laser_id == laser) return &p;
  }
  return nullptr;
}

// HDL-64E packets as the manuals lay them out: block ids alternate upper (0xEEFF) and lower (0xDDFF);
// the azimuth steps by `step` every `blocks_per_firing` blocks.
std::array<Block, 12> hdl64e_blocks(std::size_t blocks_per_firing, int step) {
  std::array<Block, 12> blocks;
  for (std::size_t b = 0; b < 12; ++b) {
    blocks[b].id = b % 2 == 0 ? 0xEEFF : 0xDDFF;
    blocks[b].azimuth = static_cast<uint16_t>(20000 + step * static_cast<int>(b / blocks_per_firing));
    for (std::size_t c = 0; c < 32; ++c) {
      blocks[b].distance[c] = static_cast<uint16_t>(5000 + 10 * c);
      blocks[b].intensity[c] = 60;
    }
  }
  return blocks;
}

TEST(VelodyneSynthetic, Hdl64eS2AndS3FiringTimes) {
  // Values hand-computed from the manuals' laser firing time tables [us after the packet's first firing]:
  // S2 (48 us per firing of a block pair, groups of 4 lasers every 6 us, 0 / 1.26 / 2.46 / 3.66 us in a
  // group) and S3 (57.6 us, 7.2 us, 0 / 1.3 / 2.5 / 3.7 us). Blocks 2k and 2k+1 hold firing k.
  struct Expected {
    std::size_t block, channel;
    double s2_us, s3_us;
  };
  const Expected expected[] = {
      {0, 0, 0.0, 0.0},     {1, 0, 0.0, 0.0},  // laser 32 fires with laser 0
      {0, 1, 1.26, 1.3},    {0, 2, 2.46, 2.5},       {0, 3, 3.66, 3.7},    {0, 4, 6.0, 7.2},
      {1, 5, 7.26, 8.5},    {0, 31, 45.66, 54.1},    {3, 10, 62.46, 74.5},  // firing 1, laser 42
      {4, 3, 99.66, 118.9}, {11, 31, 285.66, 342.1},                        // firing 5, laser 63
  };
  const auto pkt = make_packet(hdl64e_blocks(2, 17), 0, 0, 0);
  for (const VelodyneModel model : {VelodyneModel::kHDL64E, VelodyneModel::kHDL64ES3}) {
    VelodyneDecoderOptions o;
    o.model = model;
    VelodyneDecoder d(default_velodyne_calibration(model), o);
    std::vector<VelodynePoint> pts;
    const int64_t stamp = 7'000'000'000;
    ASSERT_EQ(d.decode(pkt, stamp, pts), VelodynePacketStatus::kOk) << to_string(model);
    ASSERT_EQ(pts.size(), 384u);
    EXPECT_EQ(d.model(), model);
    for (const Expected& e : expected) {
      const std::size_t laser = (e.block % 2 == 0 ? 0 : 32) + e.channel;
      const std::string what =
          std::string(to_string(model)) + " block " + std::to_string(e.block) + " channel " + std::to_string(e.channel);
      const VelodynePoint* p = find_point(pts, e.block, laser);
      ASSERT_NE(p, nullptr) << what;
      const double t_us = model == VelodyneModel::kHDL64E ? e.s2_us : e.s3_us;
      EXPECT_EQ(p->time_ns, stamp + std::llround(t_us * 1000)) << what;
      EXPECT_EQ(p->return_type, VelodyneReturnType::kStrongest) << what;
    }
    // Lasers firing together share the interpolated azimuth (no per-laser offsets in the nominal table).
    EXPECT_EQ(find_point(pts, 6, 9)->azimuth, find_point(pts, 7, 41)->azimuth);
  }
}

TEST(VelodyneSynthetic, Hdl64eDualReturnLayout) {
  // Dual return (S3 manual: upper and lower block of one firing fire together): blocks 4k, 4k+1 are
  // the upper and lower block of firing k's strongest return, 4k+2, 4k+3 of its last return; three
  // firings per packet, 57.6 us apart.
  auto blocks = hdl64e_blocks(4, 34);
  // Firing 0, upper laser 0: strongest nearer and brighter, last farther.
  blocks[0].distance[0] = 5000;
  blocks[0].intensity[0] = 90;
  blocks[2].distance[0] = 6000;
  blocks[2].intensity[0] = 10;
  // Firing 2, upper laser 7: two returns of equal intensity (the strongest-return block is strongest).
  blocks[8].distance[7] = 7000;
  blocks[10].distance[7] = 7500;
  // Firing 1, lower laser 40: only the last-return block has a return.
  blocks[5].distance[8] = 0;
  const auto pkt = make_packet(blocks, 0, 0, 0);
  VelodyneDecoderOptions o;
  o.model = VelodyneModel::kHDL64ES3;
  o.return_mode = VelodyneReturnMode::kDual;
  VelodyneDecoder d(default_velodyne_calibration(VelodyneModel::kHDL64ES3), o);
  std::vector<VelodynePoint> pts;
  ASSERT_EQ(d.decode(pkt, 0, pts), VelodynePacketStatus::kOk);
  // One point per laser and firing where both returns are the same, two where they differ.
  ASSERT_EQ(pts.size(), 3u * 64u + 2u);
  const VelodynePoint* strongest = find_point(pts, 0, 0);
  const VelodynePoint* last = find_point(pts, 2, 0);
  ASSERT_TRUE(strongest != nullptr && last != nullptr);
  EXPECT_EQ(strongest->return_type, VelodyneReturnType::kDualFirstStrongest);
  EXPECT_EQ(last->return_type, VelodyneReturnType::kDualLastWeak);
  EXPECT_EQ(strongest->time_ns, 0);
  EXPECT_EQ(last->time_ns, 0);
  EXPECT_EQ(last->azimuth, strongest->azimuth);
  EXPECT_NEAR(last->distance, 12.0, 1e-6);
  // A repeated return is kept once, from the strongest-return block.
  EXPECT_EQ(find_point(pts, 1, 32)->return_type, VelodyneReturnType::kDualOnly);
  EXPECT_EQ(find_point(pts, 3, 32), nullptr);
  // Firing 1 (blocks 4-7), lower laser 34 (channel 2): 57.6 + 2.5 us.
  EXPECT_EQ(find_point(pts, 5, 34)->time_ns, std::llround(60.1 * 1000));
  EXPECT_EQ(find_point(pts, 7, 40)->return_type, VelodyneReturnType::kDualOnly);
  EXPECT_EQ(find_point(pts, 5, 40), nullptr);
  // Firing 2 (blocks 8-11), upper laser 7: 2 * 57.6 + 7.2 + 3.7 us, both returns.
  const VelodynePoint* a = find_point(pts, 8, 7);
  const VelodynePoint* b = find_point(pts, 10, 7);
  ASSERT_TRUE(a != nullptr && b != nullptr);
  EXPECT_EQ(a->time_ns, std::llround(126.1 * 1000));
  EXPECT_EQ(b->time_ns, a->time_ns);
  EXPECT_EQ(a->return_type, VelodyneReturnType::kDualFirstStrongest);
  EXPECT_EQ(b->return_type, VelodyneReturnType::kDualLastWeak);
}

TEST(VelodyneSynthetic, RangeAndSectorLimits) {
  std::array<Block, 12> blocks;
  for (std::size_t b = 0; b < 12; ++b) {
    blocks[b].azimuth = static_cast<uint16_t>(b * 3000);  // 0, 30, ..., 330 deg
    for (std::size_t c = 0; c < 32; ++c)
      blocks[b].distance[c] = static_cast<uint16_t>(c == 0 ? 100 : 50000);  // 0.2 m, 100 m
  }
  const auto pkt = make_packet(blocks, 0x37, 0x21, 0);
  VelodyneDecoderOptions o;
  o.min_range = 0.5;
  o.max_range = 90;
  std::vector<VelodynePoint> pts;
  VelodyneDecoder(default_velodyne_calibration(VelodyneModel::kHDL32E), o).decode(pkt, 0, pts);
  EXPECT_TRUE(pts.empty());
  o.max_range = 150;
  o.sector_min_deg = 300;
  o.sector_max_deg = 60;  // wraps through 0
  pts.clear();
  VelodyneDecoder(default_velodyne_calibration(VelodyneModel::kHDL32E), o).decode(pkt, 0, pts);
  ASSERT_FALSE(pts.empty());
  for (const auto& p : pts) {
    const double deg = p.azimuth * 180 / kPi;
    EXPECT_TRUE(deg >= 300 - 1e-3 || deg <= 60 + 1e-3) << deg;
    EXPECT_NEAR(p.distance, 100, 1e-6);
  }
}

// ---------------------------------------------------------------------------------------------
// Sweep assembly and bad input

std::vector<std::vector<uint8_t>> rotating_packets(int count, int start_h, int step_per_block) {
  std::vector<std::vector<uint8_t>> out;
  int az = start_h;
  for (int i = 0; i < count; ++i) {
    std::array<Block, 12> blocks;
    for (std::size_t b = 0; b < 12; ++b) {
      blocks[b].azimuth = static_cast<uint16_t>(az % 36000);
      az += step_per_block;
      for (std::size_t c = 0; c < 32; ++c) blocks[b].distance[c] = 5000;
    }
    out.push_back(make_packet(blocks, 0x37, 0x21, static_cast<uint32_t>(i)));
  }
  return out;
}

TEST(VelodyneSweepAssembler, CutsAtTheScanPhase) {
  // HDL-32E at 600 rpm: 16.6 blocks per degree... 17 per block; 180 packets make 1.02 turns.
  const int step = 17;
  const auto packets = rotating_packets(500, 4000, step);
  VelodyneSweepOptions so;
  so.scan_phase_deg = 90;
  VelodyneSweepAssembler a(default_velodyne_calibration(VelodyneModel::kHDL32E), {}, so);
  const int64_t period_ns = 552960;  // 12 x 46.08 us
  std::vector<VelodyneSweep> sweeps;
  for (std::size_t i = 0; i < packets.size(); ++i) {
    EXPECT_EQ(a.add_packet(packets[i], static_cast<int64_t>(i) * period_ns), VelodynePacketStatus::kOk);
    while (a.has_sweep()) sweeps.push_back(a.take());
  }
  a.flush();
  while (a.has_sweep()) sweeps.push_back(a.take());
  // 500 packets x 12 x 0.17 deg = 1020 deg from 40 deg: cuts at 90, 450, 810 -> 3 full sweeps + 2 partial.
  ASSERT_EQ(sweeps.size(), 4u);
  EXPECT_FALSE(sweeps.back().complete);
  for (std::size_t s = 1; s + 1 < sweeps.size(); ++s) {
    const auto& sw = sweeps[s];
    EXPECT_TRUE(sw.complete);
    // A full turn: first point at (just past) 90 deg, last just before it, times from 0 to ~100 ms.
    const double first = sw.points.front().azimuth * 180 / kPi, last = sw.points.back().azimuth * 180 / kPi;
    EXPECT_NEAR(first, 90, 0.2) << s;
    EXPECT_NEAR(last, 90, 0.2) << s;
    EXPECT_GE(first, 90);
    EXPECT_LT(last, 90);
    EXPECT_NEAR(sw.time_offset_s(sw.points.front()), 0.0, 1e-3) << s;
    EXPECT_NEAR(sw.time_offset_s(sw.points.back()), 360 / 0.17 * 46.08e-6, 0.001) << s;  // one turn
    for (std::size_t i = 1; i < sw.points.size(); ++i) ASSERT_GE(sw.points[i].time_ns, sw.points[i - 1].time_ns);
    EXPECT_NEAR(static_cast<double>(sw.points.size()), 360.0 / 0.17 * 32, 200) << s;
  }
  EXPECT_EQ(a.stats().sweeps, 4u);
  EXPECT_EQ(a.stats().decoded, 500u);
}

TEST(VelodyneSweepAssembler, CountsBadPacketsAndNeverCrashes) {
  const auto packets = rotating_packets(400, 0, 17);
  VelodyneSweepAssembler a(default_velodyne_calibration(VelodyneModel::kHDL32E), {});
  int64_t t = 1'000'000'000;
  std::size_t fed = 0;
  auto feed = [&](std::span<const uint8_t> p, int64_t stamp) {
    ++fed;
    return a.add_packet(p, stamp);
  };
  for (std::size_t i = 0; i < 100; ++i) feed(packets[i], t += 552960);
  // Truncated, oversized, bad block id, azimuth past 360 deg, unknown return mode, wrong product.
  EXPECT_EQ(feed(std::span(packets[100]).first(700), t + 1), VelodynePacketStatus::kTruncated);
  auto longer = packets[100];
  longer.push_back(0);
  EXPECT_EQ(feed(longer, t + 1), VelodynePacketStatus::kMalformed);
  auto bad_id = packets[100];
  bad_id[300] = 0xAB;
  EXPECT_EQ(feed(bad_id, t + 1), VelodynePacketStatus::kMalformed);
  auto bad_az = packets[100];
  bad_az[1102] = 0xFF;
  bad_az[1103] = 0xFF;
  EXPECT_EQ(feed(bad_az, t + 1), VelodynePacketStatus::kMalformed);
  auto bad_mode = packets[100];
  bad_mode[1204] = 0x11;
  EXPECT_EQ(feed(bad_mode, t + 1), VelodynePacketStatus::kMalformed);
  auto other_model = packets[100];
  other_model[1205] = 0x22;  // a VLP-16 packet for a 32-laser calibration
  EXPECT_EQ(feed(other_model, t + 1), VelodynePacketStatus::kWrongModel);
  // Stamp going back, then azimuth going back within the sweep.
  EXPECT_EQ(feed(packets[100], t - 5'000'000), VelodynePacketStatus::kOutOfOrder);
  EXPECT_EQ(feed(packets[100], t += 552960), VelodynePacketStatus::kOk);
  EXPECT_EQ(feed(packets[95], t += 552960), VelodynePacketStatus::kOutOfOrder);
  const VelodyneSweepStats s = a.stats();
  EXPECT_EQ(s.truncated, 1u);
  EXPECT_EQ(s.malformed, 5u);
  EXPECT_EQ(s.out_of_order, 2u);
  EXPECT_EQ(s.decoded, 101u);
  EXPECT_EQ(s.packets, fed);

  // Fuzz: a few thousand random mutations of packets (bytes, lengths, stamps), deterministic.
  std::mt19937 rng(12345);
  std::vector<uint8_t> real;
  const auto dir = data_dir();
  if (std::filesystem::exists(dir / "vlp16")) {
    const auto raw = read_packets(dir / fixture("vlp16").model_dir);
    if (!raw.empty()) real.assign(raw[10].data.begin(), raw[10].data.end());
  }
  std::vector<std::pair<VelodyneModel, std::vector<std::vector<uint8_t>>>> runs = {
      {VelodyneModel::kHDL32E, {packets[150], packets[151], packets[152]}}};
  if (!real.empty()) runs.push_back({VelodyneModel::kVLP16, {real}});
  for (const auto& [model, seeds] : runs) {
    VelodyneSweepAssembler f(default_velodyne_calibration(model), {});
    int64_t stamp = 0;
    for (int i = 0; i < 3000; ++i) {
      std::vector<uint8_t> p = seeds[rng() % seeds.size()];
      switch (rng() % 4) {
        case 0:  // flip bytes
          for (int k = 0; k < 1 + static_cast<int>(rng() % 8); ++k) p[rng() % p.size()] = static_cast<uint8_t>(rng());
          break;
        case 1:  // truncate or extend
          p.resize(rng() % 1300);
          break;
        case 2:  // random block ids / azimuths
          p[100 * (rng() % 12) + (rng() % 4)] = static_cast<uint8_t>(rng());
          break;
        default:
          break;
      }
      stamp += static_cast<int64_t>(rng() % 2000000) - 300000;  // sometimes back in time
      f.add_packet(p, stamp);
      while (f.has_sweep()) {
        const VelodyneSweep sw = f.take();
        for (const auto& q : sw.points) ASSERT_TRUE(std::isfinite(q.x) && std::isfinite(q.y) && std::isfinite(q.z));
      }
    }
    const auto& fs = f.stats();
    EXPECT_EQ(fs.packets, 3000u);
    EXPECT_EQ(fs.decoded + fs.truncated + fs.malformed + fs.out_of_order, fs.packets);
    EXPECT_GT(fs.truncated, 0u);
    EXPECT_GT(fs.malformed, 0u);
    EXPECT_GT(fs.out_of_order, 0u);
    EXPECT_GT(fs.decoded, 0u);
  }
}

TEST(VelodyneModelNames, ParseAndPrint) {
  EXPECT_EQ(velodyne_model_from_string("VLP-16"), VelodyneModel::kVLP16);
  EXPECT_EQ(velodyne_model_from_string("vlp32c"), VelodyneModel::kVLP32C);
  EXPECT_EQ(velodyne_model_from_string("HDL-64E-S3"), VelodyneModel::kHDL64ES3);
  EXPECT_EQ(velodyne_model_from_string("HDL-64E"), VelodyneModel::kHDL64E);
  EXPECT_EQ(velodyne_model_from_string("HDL-64E S2"), VelodyneModel::kHDL64E);
  EXPECT_EQ(velodyne_model_from_string("hdl64e_s2.1"), VelodyneModel::kHDL64E);
  EXPECT_EQ(velodyne_model_from_string("HDL64E_S3"), VelodyneModel::kHDL64ES3);
  EXPECT_EQ(velodyne_model_from_string("VLS128"), VelodyneModel::kVLS128);
  EXPECT_THROW(velodyne_model_from_string("OS1"), std::invalid_argument);
  for (auto m : {VelodyneModel::kVLP16, VelodyneModel::kVLP32C, VelodyneModel::kHDL32E, VelodyneModel::kHDL64E,
                 VelodyneModel::kHDL64ES3, VelodyneModel::kVLS128}) {
    EXPECT_EQ(velodyne_model_from_string(to_string(m)), m);
  }
}

}  // namespace
}  // namespace cdc::io
