// Cloud files (common/io): KITTI .bin, the dataset's point meta side file, PCD and PLY (PCL's readers
// behind read_cloud_file). Selector % 4 picks the format.
#include "cdc/io/cloud.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace io = cdc::io;
  const cdc::fuzz::Input in(data, size);
  cdc::fuzz::refusals_pass([&] {
    switch (in.selector % 4) {
      case 0:
        (void)io::read_cloud_file(cdc::fuzz::write_file("sweep.bin", in.rest));
        break;
      case 1: {
        // A meta file for as many points as it holds (8 bytes each), or one point more or less.
        const size_t n = in.rest.size() / 8 + (in.selector / 4 % 3) - 1 + (in.rest.size() < 8 ? 1 : 0);
        std::vector<io::CloudPoint> points(n);
        io::read_point_meta(cdc::fuzz::write_file("sweep.meta", in.rest), points);
        break;
      }
      case 2:
        (void)io::read_cloud_file(cdc::fuzz::write_file("sweep.pcd", in.rest));
        break;
      default:
        (void)io::read_cloud_file(cdc::fuzz::write_file("sweep.ply", in.rest));
        break;
    }
  });
  return 0;
}
