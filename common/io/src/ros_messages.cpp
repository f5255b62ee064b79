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
#include <array>
#include <bit>
#include <cmath>
#include <initializer_list>
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

  // A builtin_interfaces/Time (int32 sec, uint32 nanosec) in nanoseconds.
  int64_t time_ns(const std::string& field) {
    const int32_t sec = num<int32_t>(field + ".sec");
    const uint32_t nanosec = num<uint32_t>(field + ".nanosec");
    return int64_t{sec} * 1'000'000'000 + int64_t{nanosec};
  }

  RosHeader header() {
    RosHeader h;
    h.stamp_ns = time_ns("header.stamp");
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

template <class T>
double load_as_double(const uint8_t* p, bool big_endian) {
  return static_cast<double>(load<T>(p, big_endian));
}

// sensor_msgs/PointField datatypes 1 (INT8) to 8 (FLOAT64), in that order.
struct Datatype {
  const char* name;
  size_t size;
  bool is_float;
  double (*read)(const uint8_t* p, bool big_endian);
};
constexpr std::array<Datatype, 8> kDatatypes{{{"INT8", 1, false, &load_as_double<int8_t>},
                                              {"UINT8", 1, false, &load_as_double<uint8_t>},
                                              {"INT16", 2, false, &load_as_double<int16_t>},
                                              {"UINT16", 2, false, &load_as_double<uint16_t>},
                                              {"INT32", 4, false, &load_as_double<int32_t>},
                                              {"UINT32", 4, false, &load_as_double<uint32_t>},
                                              {"FLOAT32", 4, true, &load_as_double<float>},
                                              {"FLOAT64", 8, true, &load_as_double<double>}}};

// The datatype numbered t, or nullptr for a number outside 1..8.
const Datatype* datatype(uint8_t t) { return t >= 1 && t <= kDatatypes.size() ? &kDatatypes[t - 1] : nullptr; }

size_t datatype_size(uint8_t t) {
  const Datatype* d = datatype(t);
  return d != nullptr ? d->size : 0;
}

const char* datatype_name(uint8_t t) {
  const Datatype* d = datatype(t);
  return d != nullptr ? d->name : "unknown";
}

bool is_float(uint8_t t) {
  const Datatype* d = datatype(t);
  return d != nullptr && d->is_float;
}

// Callers have checked the datatype (datatype_size > 0).
double read_value(const uint8_t* p, uint8_t t, bool big) {
  const Datatype* d = datatype(t);
  return d != nullptr ? d->read(p, big) : load<double>(p, big);
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

// Every field of a known type lies inside a point, and the rows inside the data.
void check_extents(const PointCloud2Msg& c) {
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
  if (count == 0) return;
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

// The fields a point is read from, and how its time field reads.
struct PointLayout {
  UsedField axis[3];
  std::optional<UsedField> intensity, ring, time;
  TimeKind time_kind = TimeKind::kRelativeSeconds;
};

// The first of `names` the cloud has, recorded in `found` (the name) and returned as a used field.
std::optional<UsedField> first_field(const PointCloud2Msg& c, std::initializer_list<const char*> names,
                                     std::string& found) {
  for (const char* name : names) {
    if (const PointFieldMsg* f = find_field(c, name)) {
      found = name;
      return use_field(c, *f);
    }
  }
  return std::nullopt;
}

// x, y and z, each a floating-point field; the optional fields under the names drivers use
// (recorded in `out`). An absolute time's unit is decided later, from the first point.
PointLayout point_layout(const PointCloud2Msg& c, DecodedCloud& out) {
  PointLayout l;
  const char* axis_names[3] = {"x", "y", "z"};
  for (int i = 0; i < 3; ++i) {
    const PointFieldMsg* f = find_field(c, axis_names[i]);
    if (f == nullptr) cloud_error(c, std::string("no field '") + axis_names[i] + "'");
    l.axis[i] = use_field(c, *f);
    if (!is_float(l.axis[i].datatype)) {
      cloud_error(c, std::string("field '") + axis_names[i] + "' has datatype " + datatype_name(l.axis[i].datatype) +
                         ", expected FLOAT32 or FLOAT64");
    }
  }
  std::string intensity_field;
  l.intensity = first_field(c, {"intensity"}, intensity_field);
  out.has_intensity = l.intensity.has_value();
  l.ring = first_field(c, {"ring", "channel", "line"}, out.ring_field);
  out.has_ring = l.ring.has_value();
  l.time = first_field(c, {"time", "t", "offset_time", "time_stamp", "timestamp"}, out.time_field);
  out.has_time = l.time.has_value();
  if (l.time && out.time_field != "timestamp") {
    l.time_kind = is_float(l.time->datatype) ? TimeKind::kRelativeSeconds : TimeKind::kRelativeNanoseconds;
  }
  return l;
}

// The header stamp split into whole seconds and the nanoseconds after them, [0, 1e9).
struct SplitStamp {
  int64_t sec = 0;
  int64_t rem_ns = 0;
};

SplitStamp split_stamp(int64_t stamp_ns) {
  SplitStamp s;
  s.sec = stamp_ns >= 0 ? stamp_ns / 1'000'000'000 : -((-stamp_ns + 999'999'999) / 1'000'000'000);
  s.rem_ns = stamp_ns - s.sec * 1'000'000'000;
  return s;
}

// Reads the points of a checked cloud through its layout.
class PointReader {
 public:
  PointReader(const PointCloud2Msg& c, const PointLayout& layout)
      : c_(c), l_(layout), big_(c.is_bigendian), stamp_(split_stamp(c.header.stamp_ns)) {}

  uint64_t count() const { return uint64_t{c_.width} * c_.height; }

  // Absolute time: seconds or nanoseconds, whichever lies within a day of the header stamp (read
  // from the first point).
  TimeKind absolute_time_kind() const {
    const double v = value(at(0), *l_.time);
    const double stamp_s = static_cast<double>(c_.header.stamp_ns) * 1e-9;
    return std::abs(v - stamp_s) < 86400.0 || std::abs(v * 1e-9 - stamp_s) >= 86400.0 ? TimeKind::kAbsoluteSeconds
                                                                                      : TimeKind::kAbsoluteNanoseconds;
  }

  // Point k; nothing when a coordinate is not finite.
  std::optional<CloudPoint> point(uint64_t k, TimeKind time_kind) const {
    const uint8_t* p = at(k);
    const double x = value(p, l_.axis[0]);
    const double y = value(p, l_.axis[1]);
    const double z = value(p, l_.axis[2]);
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(z)) return std::nullopt;
    CloudPoint q;
    q.x = static_cast<float>(x);
    q.y = static_cast<float>(y);
    q.z = static_cast<float>(z);
    if (l_.intensity) q.intensity = static_cast<float>(value(p, *l_.intensity));
    if (l_.ring) {
      const double r = value(p, *l_.ring);
      q.ring = static_cast<uint16_t>(std::isfinite(r) ? std::clamp(r, 0.0, 65535.0) : 0.0);
    }
    if (l_.time) q.time_offset = static_cast<float>(time_offset(value(p, *l_.time), time_kind));
    return q;
  }

 private:
  const uint8_t* at(uint64_t k) const {
    const uint64_t row = k / c_.width, col = k % c_.width;
    return c_.data.data() + row * c_.row_step + col * c_.point_step;
  }

  double value(const uint8_t* p, const UsedField& f) const { return read_value(p + f.offset, f.datatype, big_); }

  // Seconds after the header stamp.
  double time_offset(double v, TimeKind kind) const {
    const double sec = static_cast<double>(stamp_.sec), rem = static_cast<double>(stamp_.rem_ns);
    switch (kind) {
      case TimeKind::kRelativeSeconds:
        return v;
      case TimeKind::kRelativeNanoseconds:
        return v * 1e-9;
      case TimeKind::kAbsoluteSeconds:
        return (v - sec) - rem * 1e-9;
      case TimeKind::kAbsoluteNanoseconds:
        return (v - sec * 1e9 - rem) * 1e-9;
    }
    return 0;
  }

  const PointCloud2Msg& c_;
  const PointLayout& l_;
  bool big_;
  SplitStamp stamp_;
};

}  // namespace

DecodedCloud cloud_points(const PointCloud2Msg& c) {
  check_extents(c);
  DecodedCloud out;
  const PointLayout layout = point_layout(c, out);
  const PointReader reader(c, layout);
  const uint64_t count = reader.count();
  TimeKind time_kind = layout.time_kind;
  if (layout.time && out.time_field == "timestamp" && count > 0) {
    time_kind = reader.absolute_time_kind();
  }
  out.points.reserve(static_cast<size_t>(count));
  for (uint64_t k = 0; k < count; ++k) {
    if (const std::optional<CloudPoint> q = reader.point(k, time_kind)) out.points.push_back(*q);
  }
  return out;
}

// ------------------------------------------------------------------ message decoders

namespace {

// What every decoder does: the type checked, a ROS 1 message handed to its own decoder, else the
// CDR header and then the message's own fields, read by `read_fields(reader, msg)`.
template <class Msg, class ReadFields>
Msg decode(const BagMessage& m, std::string_view type, const char* decoder, Msg (*decode_ros1)(const BagMessage&),
           ReadFields read_fields) {
  check_type(m, type, decoder);
  if (m.serialization == Serialization::kRos1) return decode_ros1(m);
  CdrReader r(m, type);
  Msg msg;
  msg.header = r.header();
  read_fields(r, msg);
  return msg;
}

void read_point_cloud2_fields(CdrReader& r, PointCloud2Msg& c) {
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
}

void read_imu_fields(CdrReader& r, ImuMsg& imu) {
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
}

void read_velodyne_scan_fields(CdrReader& r, VelodyneScanMsg& scan) {
  // A VelodynePacket takes at least 8 (stamp) + 1206 bytes.
  const uint32_t n = r.seq("packets", 8 + kVelodynePacketBytes);
  scan.packets.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    const std::string at = "packets[" + std::to_string(i) + "]";
    VelodynePacketMsg& p = scan.packets[i];
    p.stamp_ns = r.time_ns(at + ".stamp");
    r.bytes(p.data.data(), p.data.size(), at + ".data");
  }
}

}  // namespace

PointCloud2Msg decode_point_cloud2(const BagMessage& m) {
  return decode(m, kPointCloud2Type, "decode_point_cloud2", decode_point_cloud2_ros1, read_point_cloud2_fields);
}

ImuMsg decode_imu(const BagMessage& m) { return decode(m, kImuType, "decode_imu", decode_imu_ros1, read_imu_fields); }

VelodyneScanMsg decode_velodyne_scan(const BagMessage& m) {
  return decode(m, kVelodyneScanType, "decode_velodyne_scan", decode_velodyne_scan_ros1, read_velodyne_scan_fields);
}

}  // namespace cdc::io
