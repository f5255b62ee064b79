// Recorded bags (common/io): ROS 1 .bag, ROS 2 sqlite3 .db3, MCAP and zstd-compressed storage files,
// judged by content as open_bag does, and every message of a known type decoded. Selector bit 0
// set: the input is instead a ROS 2 bag folder's metadata.yaml (its storage files absent).
#include "cdc/io/bag.hpp"
#include "cdc/io/ros_messages.hpp"
#include "fuzz_support.hpp"

namespace {

constexpr size_t kMaxMessages = 10000;  // bounds one input's work

void decode(const cdc::io::BagMessage& m) {
  namespace io = cdc::io;
  cdc::fuzz::refusals_pass([&] {
    if (m.type == io::kPointCloud2Type) {
      (void)io::cloud_points(io::decode_point_cloud2(m));
    } else if (m.type == io::kImuType) {
      (void)io::decode_imu(m);
    } else if (m.type == io::kVelodyneScanType) {
      (void)io::decode_velodyne_scan(m);
    }
  });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const cdc::fuzz::Input in(data, size);
  std::filesystem::path path;
  if ((in.selector & 1) != 0) {
    path = cdc::fuzz::write_file("folder/metadata.yaml", in.rest).parent_path();
  } else {
    std::filesystem::remove_all(cdc::fuzz::scratch_dir() / "folder");
    path = cdc::fuzz::write_file("recording", in.rest);
  }
  cdc::fuzz::refusals_pass([&] {
    const std::unique_ptr<cdc::io::BagReader> bag = cdc::io::open_bag(path);
    (void)bag->topics();
    (void)bag->describe();
    cdc::io::BagMessage m;
    for (size_t i = 0; i < kMaxMessages && bag->next(m); ++i) decode(m);
  });
  return 0;
}
