// The dataset layout's small files (common/io): dataset.json, a robot's imu.csv and calib.yaml, the
// KITTI calibration file and the Velodyne calibration YAML. Selector % 5 picks the file; for the
// Velodyne calibration, selector / 5 % 7 the model it must match (6: any).
#include "cdc/io/dataset.hpp"
#include "cdc/io/kitti.hpp"
#include "cdc/io/velodyne.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace io = cdc::io;
  const cdc::fuzz::Input in(data, size);
  cdc::fuzz::refusals_pass([&] {
    switch (in.selector % 5) {
      case 0:
        cdc::fuzz::write_file("dataset/dataset.json", in.rest);
        (void)io::read_dataset_info(cdc::fuzz::scratch_dir() / "dataset");
        break;
      case 1:
        (void)io::read_dataset_imu(cdc::fuzz::write_file("imu.csv", in.rest));
        break;
      case 2:
        (void)io::read_dataset_calib(cdc::fuzz::write_file("calib.yaml", in.rest));
        break;
      case 3: {
        const std::string path = cdc::fuzz::write_file("calib.txt", in.rest).string();
        (void)io::read_kitti_calib(path, "Tr");
        break;
      }
      default: {
        const int m = in.selector / 5 % 7;
        std::optional<io::VelodyneModel> model;
        if (m < 6) model = static_cast<io::VelodyneModel>(m);
        (void)io::read_velodyne_calibration(cdc::fuzz::write_file("velodyne.yaml", in.rest), model);
        break;
      }
    }
  });
  return 0;
}
