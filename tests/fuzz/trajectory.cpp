// Trajectory files (common/geometry): TUM, KITTI poses (with and without a times file), KITTI
// times, format detection and the seconds-as-text parser. Selector % 5 picks the reader.
#include "cdc/geometry/trajectory.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  namespace geo = cdc::geometry;
  const cdc::fuzz::Input in(data, size);
  const std::string path = cdc::fuzz::write_file("trajectory.txt", in.rest).string();
  cdc::fuzz::refusals_pass([&] {
    switch (in.selector % 5) {
      case 0: {
        const geo::Trajectory t = geo::read_tum(path);
        (void)geo::path_length(t);
        if (!t.empty()) (void)geo::interpolate_at(t, t.front().stamp_ns / 2 + t.back().stamp_ns / 2);
        break;
      }
      case 1:
        (void)geo::read_kitti(path);
        break;
      case 2: {
        // The first line holds the stamps' file, the rest the poses: a times.txt beside poses.
        const std::string_view text = in.text();
        const size_t eol = text.find('\n');
        const size_t split = eol == std::string_view::npos ? text.size() : eol + 1;
        const std::string times = cdc::fuzz::write_file("times.txt", in.rest.first(split)).string();
        const std::string poses = cdc::fuzz::write_file("poses.txt", in.rest.subspan(split)).string();
        const std::vector<int64_t> stamps = geo::read_times(times);
        (void)geo::read_kitti(poses, &stamps);
        break;
      }
      case 3:
        (void)geo::read_times(path);
        break;
      default:
        (void)geo::detect_format(path);
        (void)geo::parse_seconds_ns(std::string(in.text()));
        break;
    }
  });
  return 0;
}
