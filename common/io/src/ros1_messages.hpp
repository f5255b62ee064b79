// Decoders of the ROS 1 serialisation (little endian, unaligned, uint32 length before strings and
// variable arrays) of the message types cdc-slam imports. Each checks the message's type and every
// length against the bytes present, and throws FormatError naming the type, field and byte offset.
#pragma once

#include "cdc/io/bag.hpp"
#include "cdc/io/ros_messages.hpp"

namespace cdc::io {

PointCloud2Msg decode_point_cloud2_ros1(const BagMessage& m);
ImuMsg decode_imu_ros1(const BagMessage& m);
VelodyneScanMsg decode_velodyne_scan_ros1(const BagMessage& m);

}  // namespace cdc::io
