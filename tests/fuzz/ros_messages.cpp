// The ROS message decoders (common/io/ros_messages): PointCloud2 (and its points), Imu and
// VelodyneScan, from CDR or ROS 1 serialisation. Selector % 3 picks the type, bit 2 (of selector / 3)
// the serialisation.
#include "cdc/io/ros_messages.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace io = cdc::io;
  const cdc::fuzz::Input in(data, size);
  io::BagMessage m;
  m.topic = "/fuzz";
  m.serialization = (in.selector / 3 % 2) == 0 ? io::Serialization::kCdr : io::Serialization::kRos1;
  m.data.assign(in.rest.begin(), in.rest.end());
  cdc::fuzz::refusals_pass([&] {
    switch (in.selector % 3) {
      case 0:
        m.type = io::kPointCloud2Type;
        (void)io::cloud_points(io::decode_point_cloud2(m));
        break;
      case 1:
        m.type = io::kImuType;
        (void)io::decode_imu(m);
        break;
      default:
        m.type = io::kVelodyneScanType;
        (void)io::decode_velodyne_scan(m);
        break;
    }
  });
  return 0;
}
