// The ROS message types cdc-slam imports, decoded from CDR (ROS 2) or ROS 1 serialisation:
// sensor_msgs PointCloud2 and Imu, velodyne_msgs VelodyneScan. Decoders check every length against
// the bytes present and throw FormatError naming the field that does not fit.
#pragma once

#include "cdc/io/bag.hpp"
#include "cdc/io/cloud.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace cdc::io {

// The message types decoded here, in the ROS 2 spelling that BagMessage::type uses.
inline constexpr std::string_view kPointCloud2Type = "sensor_msgs/msg/PointCloud2";
inline constexpr std::string_view kImuType = "sensor_msgs/msg/Imu";
inline constexpr std::string_view kVelodyneScanType = "velodyne_msgs/msg/VelodyneScan";
inline constexpr size_t kVelodynePacketBytes = 1206;  // the data field of a VelodynePacket

struct RosHeader {
  int64_t stamp_ns = 0;
  std::string frame_id;
};

struct PointFieldMsg {
  std::string name;
  uint32_t offset = 0;
  uint8_t datatype = 0;  // sensor_msgs/PointField: 1 INT8 .. 8 FLOAT64
  uint32_t count = 0;
};

struct PointCloud2Msg {
  RosHeader header;
  uint32_t height = 0, width = 0;
  std::vector<PointFieldMsg> fields;
  bool is_bigendian = false;
  uint32_t point_step = 0, row_step = 0;
  std::vector<uint8_t> data;
  bool is_dense = false;
};

struct ImuMsg {
  RosHeader header;
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();     // [rad/s]
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero();  // [m/s^2]
  // Row-major 3x3 covariances as the message carries them; by ROS convention element 0 = -1 marks
  // the quantity as not provided (e.g. an IMU without orientation), all zeros means unknown.
  std::array<double, 9> orientation_covariance{};
  std::array<double, 9> angular_velocity_covariance{};
  std::array<double, 9> linear_acceleration_covariance{};
};

struct VelodynePacketMsg {
  int64_t stamp_ns = 0;
  std::array<uint8_t, kVelodynePacketBytes> data{};
};

struct VelodyneScanMsg {
  RosHeader header;
  std::vector<VelodynePacketMsg> packets;
};

// Each decoder checks m.type (sensor_msgs/msg/PointCloud2, sensor_msgs/msg/Imu,
// velodyne_msgs/msg/VelodyneScan) and decodes CDR (XCDR1, either byte order, as the encapsulation
// header says) or, for Serialization::kRos1, the ROS 1 serialisation.
PointCloud2Msg decode_point_cloud2(const BagMessage& m);
ImuMsg decode_imu(const BagMessage& m);
VelodyneScanMsg decode_velodyne_scan(const BagMessage& m);

// A PointCloud2's points (CloudPoint, cloud.hpp: fields the cloud lacks stay zero, the Sweep flags say
// which were present) and the fields the time and ring came from.
struct DecodedCloud : Sweep {
  std::string time_field;  // the field the time came from ("time", "t", ...), empty without one
  std::string ring_field;  // "ring", "channel" or "line", empty without one
};

// The points of a PointCloud2: x, y, z (FLOAT32 or FLOAT64), intensity (any numeric type), ring
// (field "ring", else "channel", else "line"; any integer type) and the per-point time, found under
// the names drivers use:
//   "time"        Velodyne driver, LIO-SAM, Hesai: FLOAT32 [s] after the header stamp
//   "t"           Ouster: UINT32 [ns] after the header stamp
//   "offset_time" Livox (converted clouds): UINT32 [ns] after the header stamp
//   "time_stamp"  nebula (Autoware): UINT32 [ns] after the header stamp
//   "timestamp"   Hesai, Livox: FLOAT64 absolute time, in [s] or [ns] (decided by which one lies within
//                 a day of the header stamp), converted to an offset from the header stamp
// A relative time field of an integer type is taken as [ns], of a floating type as [s]. The first of
// these names present is used. Points with a non-finite x, y or z are skipped. Either byte order
// (is_bigendian). Throws FormatError when a field overruns point_step, x/y/z are missing, a used
// field has an unknown datatype, or data holds fewer than height * row_step bytes.
DecodedCloud cloud_points(const PointCloud2Msg& cloud);

}  // namespace cdc::io
