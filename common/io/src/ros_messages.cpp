// CDR decoders of the ROS 2 messages cdc-slam imports, and the PointCloud2 -> points conversion.
//
// ROS 2 serialises with plain CDR (XCDR1): a 4-byte encapsulation header (0x00 0x00 big endian,
// 0x00 0x01 little endian, then two option bytes), then the fields in declaration order, each primitive
// aligned to its own size counted from the byte after the header; strings are a uint32 length that
// includes the terminating NUL, then the bytes; sequences a uint32 element count, then the elements;
// fixed arrays their elements only.
#include "cdc/io/ros_messages.hpp"

#include "ros1_messages.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>
#include <optional>
#include <string_view>
#include <type_traits>

namespace cdc::io {
namespace {

constexpr size_t kCdrHeaderBytes = 4;

template <size_t N>
using UInt = std::conditional_t<N == 1, uint8_t,
                                std::conditional_t<N == 2, uint16_t, std::conditional_t<N == 4, uint32_t, uint64_t>>>;

// A T stored at p in the given byte order.
template <class T>
T load(const uint8_t* p, bool big_endian) {
  using U = UInt<sizeof(T)>;
  U u = 0;
  for (size_t i = 0; i < sizeof(T); ++i) {
    const size_t shift = 8 * (big_endian ? sizeof(T) - 1 - i : i);
    u = static_cast<U>(u | static_cast<U>(static_cast<U>(p[i]) << shift));
  }
  return std::bit_cast<T>(u);
}

void check_type(const BagMessage& m, std::string_view expected, const char* decoder) {
  if (m.type != expected) {
    throw FormatError(std::string(decoder) + ": the message on topic '" + m.topic + "' has type '" + m.type +
                      "', expected " + std::string(expected));
  }
}

// Reads the fields of one CDR message in order, checking every length against the bytes present.
class CdrReader {
 public:
  CdrReader(const BagMessage& m, std::string_view type) : m_(m), type_(type) {
    const auto& d = m.data;
    if (d.size() < kCdrHeaderBytes) fail("encapsulation header", kCdrHeaderBytes);
    if (d[0] != 0 || d[1] > 1) {
      throw FormatError(prefix() + ": encapsulation kind 0x" + hex2(d[0]) + hex2(d[1]) +
                        " at byte offset 0 is not plain CDR (0x0000 big endian or 0x0001 little endian)");
    }
    big_endian_ = d[1] == 0;
    pos_ = kCdrHeaderBytes;
  }

  template <class T>
  T num(std::string_view field) {
    align(sizeof(T), field);
    need(sizeof(T), field);
    const T v = load<T>(m_.data.data() + pos_, big_endian_);
    pos_ += sizeof(T);
    return v;
  }
  bool boolean(std::string_view field) { return num<uint8_t>(field) != 0; }

  std::string str(std::string_view field) {
    const uint32_t n = num<uint32_t>(field);
    need(n, field);
    const char* p = reinterpret_cast<const char*>(m_.data.data() + pos_);
    pos_ += n;
    size_t len = n;
    if (len > 0 && p[len - 1] == '\0') --len;  // the terminating NUL that CDR strings carry
    return {p, len};
  }

  // A sequence length, checked against the bytes left at min_element_bytes per element.
  uint32_t seq(std::string_view field, size_t min_element_bytes) {
    align(4, field);
    const size_t at = pos_;
    const uint32_t n = num<uint32_t>(field);
    const uint64_t needed = uint64_t{n} * min_element_bytes;
    if (needed > left()) {
      throw FormatError(prefix() + ": field '" + std::string(field) + "' (sequence length at byte offset " +
                        std::to_string(at) + ") has " + std::to_string(n) + " elements needing at least " +
                        std::to_string(needed) + " bytes, only " + std::to_string(left()) + " remain");
    }
    return n;
  }

  void bytes(uint8_t* dst, size_t n, std::string_view field) {
    need(n, field);
    std::copy_n(m_.data.begin() + static_cast<std::ptrdiff_t>(pos_), n, dst);
    pos_ += n;
  }
  void bytes(std::vector<uint8_t>& dst, size_t n, std::string_view field) {
    need(n, field);
    const auto first = m_.data.begin() + static_cast<std::ptrdiff_t>(pos_);
    dst.assign(first, first + static_cast<std::ptrdiff_t>(n));
    pos_ += n;
  }

  RosHeader header() {
    RosHeader h;
    const int32_t sec = num<int32_t>("header.stamp.sec");
    const uint32_t nanosec = num<uint32_t>("header.stamp.nanosec");
    h.stamp_ns = int64_t{sec} * 1'000'000'000 + int64_t{nanosec};
    h.frame_id = str("header.frame_id");
    return h;
  }

 private:
  size_t left() const { return m_.data.size() - pos_; }

  void align(size_t n, std::string_view field) {
    const size_t pad = (n - (pos_ - kCdrHeaderBytes) % n) % n;
    need(pad, field);
    pos_ += pad;
  }

  void need(uint64_t n, std::string_view field) const {
    if (n > left()) fail(field, n);
  }

  [[noreturn]] void fail(std::string_view field, uint64_t n) const {
    throw FormatError(prefix() + ": field '" + std::string(field) + "' needs " + std::to_string(n) +
                      " bytes at byte offset " + std::to_string(pos_) + ", only " +
                      std::to_string(m_.data.size() - std::min(pos_, m_.data.size())) + " of " +
                      std::to_string(m_.data.size()) + " remain");
  }

  std::string prefix() const {
    return std::string(type_) + " (CDR) on topic '" + m_.topic + "' at log time " + std::to_string(m_.log_time_ns);
  }

  static std::string hex2(uint8_t v) {
    static const char* digits = "0123456789abcdef";
    return {digits[v >> 4], digits[v & 15]};
  }

  const BagMessage& m_;
  std::string_view type_;
  bool big_endian_ = false;
  size_t pos_ = 0;
};

// ------------------------------------------------------------------ PointCloud2 -> points

enum PointFieldType : uint8_t { kInt8 = 1, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

size_t datatype_size(uint8_t t) {
  switch (t) {
    case kInt8:
    case kUint8: return 1;
    case kInt16:
    case kUint16: return 2;
    case kInt32:
    case kUint32:
    case kFloat32: return 4;
    case kFloat64: return 8;
    default: return 0;
  }
}

const char* datatype_name(uint8_t t) {
  static const char* names[] = {"INT8", "UINT8", "INT16", "UINT16", "INT32", "UINT32", "FLOAT32", "FLOAT64"};
  return t >= kInt8 && t <= kFloat64 ? names[t - 1] : "unknown";
}

bool is_float(uint8_t t) { return t == kFloat32 || t == kFloat64; }

double read_value(const uint8_t* p, uint8_t t, bool big) {
  switch (t) {
    case kInt8: return load<int8_t>(p, big);
    case kUint8: return load<uint8_t>(p, big);
    case kInt16: return load<int16_t>(p, big);
    case kUint16: return load<uint16_t>(p, big);
    case kInt32: return load<int32_t>(p, big);
    case kUint32: return load<uint32_t>(p, big);
    case kFloat32: return load<float>(p, big);
    default: return load<double>(p, big);
  }
}

[[noreturn]] void cloud_error(const PointCloud2Msg& c, const std::string& what) {
  throw FormatError("sensor_msgs/msg/PointCloud2 (frame '" + c.header.frame_id + "', stamp " +
                    std::to_string(c.header.stamp_ns) + " ns): " + what);
}

const PointFieldMsg* find_field(const PointCloud2Msg& c, std::string_view name) {
  for (const auto& f : c.fields) {
    if (f.name == name) return &f;
  }
  return nullptr;
}

// A used field: its offset and type, checked.
struct UsedField {
  uint32_t offset = 0;
  uint8_t datatype = 0;
};

UsedField use_field(const PointCloud2Msg& c, const PointFieldMsg& f) {
  if (datatype_size(f.datatype) == 0) {
    cloud_error(c, "field '" + f.name + "' has unknown datatype " + std::to_string(f.datatype));
  }
  return {f.offset, f.datatype};
}

// How a time field's values turn into seconds after the header stamp.
enum class TimeKind { kRelativeSeconds, kRelativeNanoseconds, kAbsoluteSeconds, kAbsoluteNanoseconds };

}  // namespace

DecodedCloud cloud_points(const PointCloud2Msg& c) {
  // Every field of a known type must lie inside a point.
  for (const auto& f : c.fields) {
    const size_t size = datatype_size(f.datatype);
    if (size == 0) continue;
    const uint64_t end = uint64_t{f.offset} + size * std::max<uint64_t>(f.count, 1);
    if (end > c.point_step) {
      cloud_error(c, "field '" + f.name + "' (offset " + std::to_string(f.offset) + ", " + datatype_name(f.datatype) +
                         " x" + std::to_string(f.count) + ") ends at byte " + std::to_string(end) +
                         " of a point, beyond point_step " + std::to_string(c.point_step));
    }
  }
  const uint64_t count = uint64_t{c.width} * c.height;
  if (count > 0) {
    if (c.point_step == 0) cloud_error(c, "point_step is 0 for " + std::to_string(count) + " points");
    if (uint64_t{c.width} * c.point_step > c.row_step) {
      cloud_error(c, "row_step " + std::to_string(c.row_step) + " is shorter than width " + std::to_string(c.width) +
                         " x point_step " + std::to_string(c.point_step));
    }
    if (uint64_t{c.height} * c.row_step > c.data.size()) {
      cloud_error(c, "data holds " + std::to_string(c.data.size()) + " bytes, height " + std::to_string(c.height) +
                         " x row_step " + std::to_string(c.row_step) + " needs " +
                         std::to_string(uint64_t{c.height} * c.row_step));
    }
  }
  UsedField axis[3];
  const char* axis_names[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    const PointFieldMsg* f = find_field(c, axis_names[i]);
    if (f == nullptr) cloud_error(c, std::string("no field '") + axis_names[i] + "'");
    axis[i] = use_field(c, *f);
    if (!is_float(axis[i].datatype)) {
      cloud_error(c, std::string("field '") + axis_names[i] + "' has datatype " + datatype_name(axis[i].datatype) +
                         ", expected FLOAT32 or FLOAT64");
    }
  }

  DecodedCloud out;
  std::optional<UsedField> intensity, ring, time;
  if (const PointFieldMsg* f = find_field(c, "intensity")) {
    intensity = use_field(c, *f);
    out.has_intensity = true;
  }
  for (const char* name : {"ring", "channel", "line"}) {
    if (const PointFieldMsg* f = find_field(c, name)) {
      ring = use_field(c, *f);
      out.has_ring = true;
      out.ring_field = name;
      break;
    }
  }
  TimeKind time_kind = TimeKind::kRelativeSeconds;
  for (const char* name : {"time", "t", "offset_time", "time_stamp", "timestamp"}) {
    if (const PointFieldMsg* f = find_field(c, name)) {
      time = use_field(c, *f);
      out.has_time = true;
      out.time_field = name;
      if (out.time_field != "timestamp") {
        time_kind = is_float(time->datatype) ? TimeKind::kRelativeSeconds : TimeKind::kRelativeNanoseconds;
      }
      break;
    }
  }

  const bool big = c.is_bigendian;
  const int64_t stamp_sec = c.header.stamp_ns >= 0 ? c.header.stamp_ns / 1'000'000'000
                                                   : -((-c.header.stamp_ns + 999'999'999) / 1'000'000'000);
  const int64_t stamp_rem = c.header.stamp_ns - stamp_sec * 1'000'000'000;  // [0, 1e9)
  const auto point_at = [&](uint64_t k) {
    const uint64_t row = k / c.width, col = k % c.width;
    return c.data.data() + row * c.row_step + col * c.point_step;
  };
  if (time && out.time_field == "timestamp" && count > 0) {
    // Absolute time: seconds or nanoseconds, whichever lies within a day of the header stamp.
    const double v = read_value(point_at(0) + time->offset, time->datatype, big);
    const double stamp_s = static_cast<double>(c.header.stamp_ns) * 1e-9;
    time_kind = std::abs(v - stamp_s) < 86400.0 || std::abs(v * 1e-9 - stamp_s) >= 86400.0
                    ? TimeKind::kAbsoluteSeconds
                    : TimeKind::kAbsoluteNanoseconds;
  }

  out.points.reserve(static_cast<size_t>(count));
  for (uint64_t k = 0; k < count; ++k) {
    const uint8_t* p = point_at(k);
    CloudPoint q;
    const double x = read_value(p + axis[0].offset, axis[0].datatype, big);
    const double y = read_value(p + axis[1].offset, axis[1].datatype, big);
    const double z = read_value(p + axis[2].offset, axis[2].datatype, big);
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) continue;
    q.x = static_cast<float>(x);
    q.y = static_cast<float>(y);
    q.z = static_cast<float>(z);
    if (intensity) q.intensity = static_cast<float>(read_value(p + intensity->offset, intensity->datatype, big));
    if (ring) {
      const double r = read_value(p + ring->offset, ring->datatype, big);
      q.ring = static_cast<uint16_t>(std::isfinite(r) ? std::clamp(r, 0.0, 65535.0) : 0.0);
    }
    if (time) {
      const double v = read_value(p + time->offset, time->datatype, big);
      double offset = 0;
      switch (time_kind) {
        case TimeKind::kRelativeSeconds: offset = v; break;
        case TimeKind::kRelativeNanoseconds: offset = v * 1e-9; break;
        case TimeKind::kAbsoluteSeconds:
          offset = (v - static_cast<double>(stamp_sec)) - static_cast<double>(stamp_rem) * 1e-9;
          break;
        case TimeKind::kAbsoluteNanoseconds:
          offset = (v - static_cast<double>(stamp_sec) * 1e9 - static_cast<double>(stamp_rem)) * 1e-9;
          break;
      }
      q.time_offset = static_cast<float>(offset);
    }
    out.points.push_back(q);
  }
  return out;
}

// ------------------------------------------------------------------ message decoders

PointCloud2Msg decode_point_cloud2(const BagMessage& m) {
  check_type(m, kPointCloud2Type, "decode_point_cloud2");
  if (m.serialization == Serialization::kRos1) return decode_point_cloud2_ros1(m);
  CdrReader r(m, kPointCloud2Type);
  PointCloud2Msg c;
  c.header = r.header();
  c.height = r.num<uint32_t>("height");
  c.width = r.num<uint32_t>("width");
  // A PointField takes at least 13 bytes: name length, offset, datatype, count.
  const uint32_t n_fields = r.seq("fields", 13);
  c.fields.resize(n_fields);
  for (uint32_t i = 0; i < n_fields; ++i) {
    const std::string at = "fields[" + std::to_string(i) + "]";
    PointFieldMsg& f = c.fields[i];
    f.name = r.str(at + ".name");
    f.offset = r.num<uint32_t>(at + ".offset");
    f.datatype = r.num<uint8_t>(at + ".datatype");
    f.count = r.num<uint32_t>(at + ".count");
  }
  c.is_bigendian = r.boolean("is_bigendian");
  c.point_step = r.num<uint32_t>("point_step");
  c.row_step = r.num<uint32_t>("row_step");
  const uint32_t n_data = r.seq("data", 1);
  r.bytes(c.data, n_data, "data");
  c.is_dense = r.boolean("is_dense");
  return c;
}

ImuMsg decode_imu(const BagMessage& m) {
  check_type(m, kImuType, "decode_imu");
  if (m.serialization == Serialization::kRos1) return decode_imu_ros1(m);
  CdrReader r(m, kImuType);
  ImuMsg imu;
  imu.header = r.header();
  const double qx = r.num<double>("orientation.x");
  const double qy = r.num<double>("orientation.y");
  const double qz = r.num<double>("orientation.z");
  const double qw = r.num<double>("orientation.w");
  imu.orientation = Eigen::Quaterniond(qw, qx, qy, qz);
  for (size_t i = 0; i < 9; ++i) imu.orientation_covariance[i] = r.num<double>("orientation_covariance");
  for (int i = 0; i < 3; ++i) imu.angular_velocity[i] = r.num<double>("angular_velocity");
  for (size_t i = 0; i < 9; ++i) imu.angular_velocity_covariance[i] = r.num<double>("angular_velocity_covariance");
  for (int i = 0; i < 3; ++i) imu.linear_acceleration[i] = r.num<double>("linear_acceleration");
  for (size_t i = 0; i < 9; ++i) {
    imu.linear_acceleration_covariance[i] = r.num<double>("linear_acceleration_covariance");
  }
  return imu;
}

VelodyneScanMsg decode_velodyne_scan(const BagMessage& m) {
  check_type(m, kVelodyneScanType, "decode_velodyne_scan");
  if (m.serialization == Serialization::kRos1) return decode_velodyne_scan_ros1(m);
  CdrReader r(m, kVelodyneScanType);
  VelodyneScanMsg scan;
  scan.header = r.header();
  // A VelodynePacket takes at least 8 (stamp) + 1206 bytes.
  const uint32_t n = r.seq("packets", 8 + kVelodynePacketBytes);
  scan.packets.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    const std::string at = "packets[" + std::to_string(i) + "]";
    VelodynePacketMsg& p = scan.packets[i];
    const int32_t sec = r.num<int32_t>(at + ".stamp.sec");
    const uint32_t nanosec = r.num<uint32_t>(at + ".stamp.nanosec");
    p.stamp_ns = int64_t{sec} * 1'000'000'000 + int64_t{nanosec};
    r.bytes(p.data.data(), p.data.size(), at + ".data");
  }
  return scan;
}

}  // namespace cdc::io
