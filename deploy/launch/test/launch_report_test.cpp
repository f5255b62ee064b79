// Pure helpers of the launcher's reports (no processes, no DDS).
#include "report.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <unistd.h>

namespace fs = std::filesystem;

namespace cdc::launch {
namespace {

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("launch_report_test_" + std::to_string(::getpid()))) {
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

// A TUM trajectory along x at 10 Hz; from `from` on, every position is shifted by `dz` in z.
void write_tum(const std::string& path, int n, int from, double dz, double stamp_offset_s = 0) {
  std::ofstream out(path);
  out.precision(9);
  for (int i = 0; i < n; ++i) {
    out << 0.1 * i + stamp_offset_s << ' ' << 1.0 * i << " 0 " << (i >= from ? dz : 0.0) << " 0 0 0 1\n";
  }
}

TEST(PositionDifference, RmsAndLargestDistanceAtMatchingStamps) {
  TempDir dir;
  write_tum(dir.file("c.tum"), 100, 100, 0.0);
  write_tum(dir.file("d.tum"), 100, 75, 0.2);  // the last quarter moved up by 0.2 m
  const auto d = position_difference(dir.file("c.tum"), dir.file("d.tum"));
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->matched, 100u);
  EXPECT_NEAR(d->max_m, 0.2, 1e-9);
  EXPECT_NEAR(d->rms_m, 0.1, 1e-9);  // sqrt(0.25 * 0.04)
}

TEST(PositionDifference, IdenticalTrajectoriesDoNotDiffer) {
  TempDir dir;
  write_tum(dir.file("a.tum"), 50, 50, 0.0);
  const auto d = position_difference(dir.file("a.tum"), dir.file("a.tum"));
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->matched, 50u);
  EXPECT_EQ(d->rms_m, 0.0);
  EXPECT_EQ(d->max_m, 0.0);
}

TEST(PositionDifference, MissingFilesOrNoCommonStampsGiveNothing) {
  TempDir dir;
  write_tum(dir.file("a.tum"), 20, 20, 0.0);
  write_tum(dir.file("late.tum"), 20, 20, 0.0, 100.0);  // no stamp within 5 ms of a's
  EXPECT_FALSE(position_difference(dir.file("a.tum"), dir.file("missing.tum")).has_value());
  EXPECT_FALSE(position_difference(dir.file("missing.tum"), dir.file("a.tum")).has_value());
  EXPECT_FALSE(position_difference(dir.file("a.tum"), dir.file("late.tum")).has_value());
}

}  // namespace
}  // namespace cdc::launch
