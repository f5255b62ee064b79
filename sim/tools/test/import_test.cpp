#include "import.hpp"

#include "cdc/io/cloud.hpp"
#include "cdc/io/dataset.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>

namespace cdc::sim {
namespace {
namespace fs = std::filesystem;

using test::read_file;

fs::path temp_dir(const std::string& name) { return test::fresh_temp_dir("import_" + name); }

// A KITTI-style sequence: n sweeps of random points, times 0.5 s apart from 100 s, LiDAR poses on a
// straight line out to 2 m per sweep.
fs::path make_sequence(const fs::path& root, size_t n) {
  const fs::path dir = root / "seq";
  fs::create_directories(dir / "velodyne");
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-20, 20);
  std::ofstream times(dir / "times.txt"), poses(dir / "poses.txt");
  for (size_t i = 0; i < n; ++i) {
    std::vector<io::CloudPoint> pts(50 + i);
    for (auto& p : pts) p = {u(rng), u(rng), u(rng) / 10, 0.5f, 0, 0};
    char name[32];
    std::snprintf(name, sizeof name, "%06zu.bin", i);
    io::write_kitti_bin(dir / "velodyne" / name, pts);
    times << 100.0 + 0.5 * static_cast<double>(i) << '\n';
    poses << "1 0 0 " << 2.0 * static_cast<double>(i) << " 0 1 0 0 0 0 1 0\n";
  }
  return dir;
}

io::KittiSequenceOptions lidar_poses(const fs::path& seq) {
  io::KittiSequenceOptions o;
  o.poses = seq / "poses.txt";
  o.poses_frame = io::KittiPosesFrame::kLidar;
  return o;
}

// Each test works in a fresh folder, root, that is removed when the test ends; the dataset is written to
// root/ds.
class Import : public ::testing::Test {
 protected:
  void use_folder(const std::string& name) {
    root = temp_dir(name);
    o.out = root / "ds";
  }
  void TearDown() override {
    if (!root.empty()) fs::remove_all(root);
  }

  fs::path root;
  ImportOptions o;
};

TEST_F(Import, KittiSplitIntoRobotsKeepsEverySweepItsPoseAndMakesTheRadioFromThePoses) {
  use_folder("split");
  const fs::path seq = make_sequence(root, 60);
  const Recording rec = kitti_recording(seq, lidar_poses(seq), io::PointTimes::kNone, "ground_truth");
  o.robots = 3;
  o.time_shift_s = 1.0;
  o.radio.central_range_m = 30;  // robots 1 and 2 start 40 and 80 m away from robot 0's start
  const ImportSummary sum = write_import(rec, o);
  EXPECT_EQ(sum.info.robots, 3u);
  EXPECT_EQ(sum.info.radio, "reference_poses");
  EXPECT_GT(sum.info.out_of_range_periods, 0u);
  const io::DatasetInfo info = io::read_dataset_info(o.out);
  EXPECT_EQ(info.point_times, io::PointTimes::kNone);
  EXPECT_NEAR(info.sweep_period_s, 0.5, 1e-9);
  EXPECT_EQ(info.poses, "ground_truth");
  io::SplitOptions split;
  split.time_shift_s = 1.0;  // three robots, 0.15 overlap
  const auto ranges = io::split_ranges(60, split);
  std::map<uint32_t, geometry::Trajectory> gt;
  const auto scans = io::list_dataset_scans(o.out.string(), 0, &gt);
  size_t total = 0;
  for (uint32_t r = 0; r < 3; ++r) {
    const auto& range = ranges[r];
    ASSERT_EQ(gt[r].size(), range.last - range.first);
    total += gt[r].size();
    for (size_t i = range.first; i < range.last; ++i) {
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.bin", i - range.first);
      char src[32];
      std::snprintf(src, sizeof src, "%06zu.bin", i);
      EXPECT_EQ(read_file(o.out / ("robot_" + std::to_string(r)) / "velodyne" / name),
                read_file(seq / "velodyne" / src));
      const auto& sp = gt[r][i - range.first];
      EXPECT_EQ(sp.stamp_ns,
                static_cast<int64_t>(r) * 1'000'000'000 + static_cast<int64_t>(i - range.first) * 500'000'000);
      EXPECT_NEAR(sp.pose.translation().x(), 2.0 * static_cast<double>(i), 1e-9);
    }
    EXPECT_FALSE(fs::exists(o.out / ("robot_" + std::to_string(r)) / "velodyne_meta"));
  }
  EXPECT_EQ(scans.size(), total);
  EXPECT_TRUE(fs::exists(o.out / "radio.csv"));
  // Robot 2 starts far beyond the central's 30 m: out of range at the start.
  std::ifstream periods(o.out / "radio_periods.csv");
  std::string text((std::istreambuf_iterator<char>(periods)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("2,200,"), std::string::npos) << text;
}

TEST_F(Import, AzimuthTimesAreWrittenOnlyWhenAskedForAndLieWithinTheSweep) {
  use_folder("azimuth");
  const fs::path seq = make_sequence(root, 5);
  write_import(kitti_recording(seq, {}, io::PointTimes::kAzimuth, "none"), o);
  EXPECT_EQ(io::read_dataset_info(o.out).point_times, io::PointTimes::kAzimuth);
  const auto scans = io::list_dataset_scans(o.out.string());
  ASSERT_EQ(scans.size(), 5u);
  const io::Sweep s = io::read_dataset_scan(scans[0]);
  ASSERT_TRUE(s.has_time);
  for (const auto& p : s.points) {
    EXPECT_GE(p.time_offset, 0.0f);
    EXPECT_LE(p.time_offset, 0.5f);
  }
}

TEST_F(Import, AFailedImportLeavesNoDatasetBehind) {
  use_folder("fail");
  const fs::path seq = make_sequence(root, 30);
  o.robots = 3;
  // Several robots with poses but no range: refused before anything is committed.
  EXPECT_THROW(write_import(kitti_recording(seq, lidar_poses(seq), io::PointTimes::kNone, "ground_truth"), o),
               std::invalid_argument);
  EXPECT_FALSE(fs::exists(o.out));
  EXPECT_FALSE(fs::exists(root / "ds.partial"));
  // A sweep that disappears after listing (a damaged recording): the import stops, nothing is left.
  Recording rec = kitti_recording(seq, lidar_poses(seq), io::PointTimes::kNone, "ground_truth");
  fs::remove(seq / "velodyne" / "000020.bin");
  o.radio.central_range_m = 100;
  EXPECT_THROW(write_import(rec, o), std::exception);
  EXPECT_FALSE(fs::exists(o.out));
  EXPECT_FALSE(fs::exists(root / "ds.partial"));
  // And the listing itself names the missing sweep.
  try {
    kitti_recording(seq, {}, io::PointTimes::kNone, "none");
    FAIL() << "a sequence with a missing sweep was accepted";
  } catch (const io::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("000020.bin"), std::string::npos) << e.what();
  }
}

TEST_F(Import, SweepFolderOfPcdFilesKeepsTheirPointTimesAndRings) {
  use_folder("pcd");
  const fs::path dir = root / "sweeps";
  fs::create_directories(dir);
  for (int k = 0; k < 3; ++k) {
    std::ofstream f(dir / ("scan_" + std::to_string(k) + ".pcd"));
    f << "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity ring time\nSIZE 4 4 4 4 2 4\nTYPE F F F F U F\n"
         "COUNT 1 1 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA ascii\n";
    for (int i = 0; i < 3; ++i) f << 1.0 + i << ' ' << k << " 0.5 " << 10 * i << ' ' << i << ' ' << 0.01 * i << '\n';
  }
  std::ofstream(dir / "times.txt") << "5.0\n5.1\n5.2\n";
  const ImportSummary sum = write_import(sweep_folder_recording(dir, {}), o);
  EXPECT_EQ(sum.info.point_times, io::PointTimes::kSensor);
  EXPECT_EQ(sum.info.scans, 3u);
  const auto scans = io::list_dataset_scans(o.out.string());
  ASSERT_EQ(scans.size(), 3u);
  EXPECT_EQ(scans[2].stamp_ns, 200'000'000);
  const io::Sweep s = io::read_dataset_scan(scans[1]);
  ASSERT_EQ(s.points.size(), 3u);
  EXPECT_FLOAT_EQ(s.points[2].x, 3.0f);
  EXPECT_FLOAT_EQ(s.points[2].y, 1.0f);
  EXPECT_FLOAT_EQ(s.points[2].time_offset, 0.02f);
  EXPECT_EQ(s.points[2].ring, 2);
}

TEST_F(Import, RealBalmSweepsSplitIntoThreeOverlappingRobots) {
  const char* env = std::getenv("CDC_DATA_DIR");
  const fs::path data = fs::path(env != nullptr ? env : "../shared/data") / "real/balm_10cm";
  if (!fs::exists(data / "poses.txt")) GTEST_SKIP() << "real data absent: " << data << " not found (set CDC_DATA_DIR)";
  use_folder("balm");
  o.robots = 3;
  o.radio.central_range_m = 8;
  o.max_scans = 5;
  const ImportSummary sum = write_import(sweep_folder_recording(data, {"", data / "poses.txt", "reference", 0.5}), o);
  EXPECT_EQ(sum.info.robots, 3u);
  EXPECT_EQ(sum.info.scans, 15u);
  EXPECT_EQ(sum.info.point_times, io::PointTimes::kNone);
  EXPECT_EQ(sum.info.poses, "reference");
  EXPECT_NEAR(sum.info.sweep_period_s, 0.5, 0.01);
}

}  // namespace
}  // namespace cdc::sim
