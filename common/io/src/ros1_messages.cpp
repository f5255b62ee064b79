// ROS 1 serialisation: fields in declaration order, little endian, no alignment; bool and uint8 are
// one byte; time is uint32 sec + uint32 nsec; strings and variable-length arrays start with a uint32
// element count; fixed-length arrays (uint8[1206], float64[9]) have none.

#include "ros1_messages.hpp"

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <string_view>

namespace cdc::io {
namespace {

constexpr size_t kTimeBytes = 8;
constexpr size_t kCovarianceDoubles = 9;
constexpr uint32_t kPointFieldMinBytes = 4 + 4 + 1 + 4;  // empty name, offset, datatype, count

// Reads one message's bytes front to back; every read checks the bytes left and names the field.
class Ros1Cursor {
 public:
  Ros1Cursor(const BagMessage& m, std::string_view expected_type) : m_(m), type_(expected_type) {
    if (m.serialization != Serialization::kRos1) {
      throw FormatError("ROS 1 decoder for " + type_ + ": message on " + m.topic + " is not in ROS 1 serialisation");
    }
    if (m.type != expected_type) {
      throw FormatError("ROS 1 decoder for " + type_ + ": message on " + m.topic + " has type '" + m.type + "'");
    }
  }

  std::span<const uint8_t> take(const char* field, uint64_t n) {
    if (n > m_.data.size() - pos_) fail(field, "needs " + std::to_string(n) + " bytes");
    const std::span<const uint8_t> out(m_.data.data() + pos_, static_cast<size_t>(n));
    pos_ += static_cast<size_t>(n);
    return out;
  }
  uint8_t u8(const char* field) { return take(field, 1)[0]; }
  bool boolean(const char* field) { return u8(field) != 0; }
  uint32_t u32(const char* field) {
    const std::span<const uint8_t> b = take(field, 4);
    return static_cast<uint32_t>(b[0]) | (static_cast<uint32_t>(b[1]) << 8u) | (static_cast<uint32_t>(b[2]) << 16u) |
           (static_cast<uint32_t>(b[3]) << 24u);
  }
  double f64(const char* field) {
    const std::span<const uint8_t> b = take(field, 8);
    uint64_t bits = 0;
    for (size_t i = 0; i < 8; ++i) bits |= static_cast<uint64_t>(b[i]) << (8u * i);
    double v = 0;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  }
  int64_t time_ns(const char* field) {
    const int64_t sec = u32(field);
    const int64_t nsec = u32(field);
    return sec * 1'000'000'000 + nsec;
  }
  std::string str(const char* field) {
    const uint32_t n = u32(field);
    const std::span<const uint8_t> b = take(field, n);
    return {reinterpret_cast<const char*>(b.data()), b.size()};
  }
  // Element count of a variable-length array whose elements take at least min_element_bytes each.
  uint32_t count(const char* field, uint64_t min_element_bytes) {
    const size_t at = pos_;
    const uint32_t n = u32(field);
    if (n * min_element_bytes > m_.data.size() - pos_) {
      pos_ = at;
      fail(field, "declares " + std::to_string(n) + " elements of at least " + std::to_string(min_element_bytes) +
                      " bytes after its 4-byte length");
    }
    return n;
  }
  RosHeader header() {
    RosHeader h;
    u32("header.seq");
    h.stamp_ns = time_ns("header.stamp");
    h.frame_id = str("header.frame_id");
    return h;
  }
  void finish() {
    if (pos_ != m_.data.size()) {
      throw FormatError(where() + ": " + std::to_string(m_.data.size() - pos_) +
                        " bytes follow the end of the message");
    }
  }
  [[noreturn]] void invalid(const std::string& what) const { throw FormatError(where() + ": " + what); }

 private:
  std::string where() const {
    return "ROS 1 " + type_ + " on " + m_.topic + " (" + std::to_string(m_.data.size()) + " bytes)";
  }
  [[noreturn]] void fail(const char* field, const std::string& need) const {
    throw FormatError(where() + ": field '" + field + "' at byte " + std::to_string(pos_) + " " + need + ", " +
                      std::to_string(m_.data.size() - pos_) + " remain");
  }

  const BagMessage& m_;
  std::string type_;
  size_t pos_ = 0;
};

uint32_t point_field_size(uint8_t datatype) {
  switch (datatype) {
    case 1:  // INT8
    case 2:  // UINT8
      return 1;
    case 3:  // INT16
    case 4:  // UINT16
      return 2;
    case 5:  // INT32
    case 6:  // UINT32
    case 7:  // FLOAT32
      return 4;
    case 8:  // FLOAT64
      return 8;
    default:
      return 0;
  }
}

}  // namespace

PointCloud2Msg decode_point_cloud2_ros1(const BagMessage& m) {
  Ros1Cursor in(m, kPointCloud2Type);
  PointCloud2Msg msg;
  msg.header = in.header();
  msg.height = in.u32("height");
  msg.width = in.u32("width");
  const uint32_t n_fields = in.count("fields", kPointFieldMinBytes);
  msg.fields.resize(n_fields);
  for (PointFieldMsg& f : msg.fields) {
    f.name = in.str("fields.name");
    f.offset = in.u32("fields.offset");
    f.datatype = in.u8("fields.datatype");
    f.count = in.u32("fields.count");
  }
  msg.is_bigendian = in.boolean("is_bigendian");
  msg.point_step = in.u32("point_step");
  msg.row_step = in.u32("row_step");
  const uint32_t n_data = in.count("data", 1);
  const std::span<const uint8_t> data = in.take("data", n_data);
  msg.data.assign(data.begin(), data.end());
  msg.is_dense = in.boolean("is_dense");
  in.finish();

  if (uint64_t{msg.row_step} * msg.height != msg.data.size()) {
    in.invalid("data holds " + std::to_string(msg.data.size()) +
               " bytes, row_step * height = " + std::to_string(msg.row_step) + " * " + std::to_string(msg.height) +
               " = " + std::to_string(uint64_t{msg.row_step} * msg.height));
  }
  if (uint64_t{msg.point_step} * msg.width > msg.row_step) {
    in.invalid("point_step * width = " + std::to_string(msg.point_step) + " * " + std::to_string(msg.width) +
               " exceeds row_step " + std::to_string(msg.row_step));
  }
  for (const PointFieldMsg& f : msg.fields) {
    const uint32_t size = point_field_size(f.datatype);
    if (size == 0) {
      in.invalid("point field '" + f.name + "' has unknown datatype " + std::to_string(f.datatype));
    }
    if (uint64_t{f.offset} + uint64_t{size} * f.count > msg.point_step) {
      in.invalid("point field '" + f.name + "' (offset " + std::to_string(f.offset) + ", " + std::to_string(f.count) +
                 " x " + std::to_string(size) + " bytes) does not fit in point_step " + std::to_string(msg.point_step));
    }
  }
  return msg;
}

ImuMsg decode_imu_ros1(const BagMessage& m) {
  Ros1Cursor in(m, kImuType);
  ImuMsg msg;
  msg.header = in.header();
  const double qx = in.f64("orientation.x");
  const double qy = in.f64("orientation.y");
  const double qz = in.f64("orientation.z");
  const double qw = in.f64("orientation.w");
  msg.orientation = Eigen::Quaterniond(qw, qx, qy, qz);
  in.take("orientation_covariance", kCovarianceDoubles * 8);
  msg.angular_velocity.x() = in.f64("angular_velocity.x");
  msg.angular_velocity.y() = in.f64("angular_velocity.y");
  msg.angular_velocity.z() = in.f64("angular_velocity.z");
  in.take("angular_velocity_covariance", kCovarianceDoubles * 8);
  msg.linear_acceleration.x() = in.f64("linear_acceleration.x");
  msg.linear_acceleration.y() = in.f64("linear_acceleration.y");
  msg.linear_acceleration.z() = in.f64("linear_acceleration.z");
  in.take("linear_acceleration_covariance", kCovarianceDoubles * 8);
  in.finish();
  return msg;
}

VelodyneScanMsg decode_velodyne_scan_ros1(const BagMessage& m) {
  Ros1Cursor in(m, kVelodyneScanType);
  VelodyneScanMsg msg;
  msg.header = in.header();
  const uint32_t n = in.count("packets", kTimeBytes + kVelodynePacketBytes);
  msg.packets.resize(n);
  for (VelodynePacketMsg& p : msg.packets) {
    p.stamp_ns = in.time_ns("packets.stamp");
    const std::span<const uint8_t> data = in.take("packets.data", kVelodynePacketBytes);
    std::memcpy(p.data.data(), data.data(), kVelodynePacketBytes);
  }
  in.finish();
  return msg;
}

}  // namespace cdc::io
