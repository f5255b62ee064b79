// Bags written from a dataset by independent writers (python3-rosbag; db3 and MCAP from the format
// specifications) import back to the same sweeps, times and IMU samples; damaged bags are refused
// without leaving a dataset behind.
#include "import.hpp"

#include "cdc/io/bag.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/dataset.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>

namespace cdc::sim {
namespace {
namespace fs = std::filesystem;

using test::read_file;

class ImportBag : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = test::fresh_test_dir("import_bag");
    // A robot with 4 sweeps (per-point times and rings) and 200 Hz IMU, starting at 12.3 s.
    io::DatasetWriter w(root_ / "source");
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-30, 30);
    for (int k = 0; k < 4; ++k) {
      io::Sweep s;
      s.has_time = s.has_ring = s.has_intensity = true;
      for (int i = 0; i < 500 + 10 * k; ++i) {
        s.points.push_back({u(rng), u(rng), u(rng) / 10, 0.01f * static_cast<float>(i % 100),
                            0.1f * static_cast<float>(i) / 600.0f, static_cast<uint16_t>(i % 32)});
      }
      w.add_sweep(0, 12'300'000'000 + k * 100'000'123, s);
    }
    std::vector<io::DatasetImu> imu;
    for (int i = 0; i < 90; ++i) {
      imu.push_back({12'290'000'000 + i * 5'000'000, Eigen::Vector3d(0.1 * i, -0.5, 9.81),
                     Eigen::Vector3d(0.01, 0.002 * i, -0.03)});
    }
    w.set_imu(0, imu);
    w.commit({});
  }
  void TearDown() override { fs::remove_all(root_); }

  // Runs the independent writer; the path of the bag it wrote.
  fs::path write_bag(const std::string& format, const std::string& extra = "") {
    const fs::path out = root_ / (format == "db3" ? "bag_db3" : "bag." + format);
    const std::string cmd = std::string(CDC_PYTHON3) + " " + CDC_DATASET_TO_BAG + " " + (root_ / "source").string() +
                            " " + out.string() + " --format " + format + extra;
    const int rc = std::system(cmd.c_str());
    EXPECT_TRUE(WIFEXITED(rc) && WEXITSTATUS(rc) == 0) << cmd;
    return out;
  }

  void expect_round_trip(const fs::path& bag) {
    ImportOptions o;
    o.out = root_ / "imported";
    ImportSummary sum;
    {
      const Recording rec = bag_recording(bag, {}, root_ / "imported.extract");
      EXPECT_TRUE(fs::exists(root_ / "imported.extract"));
      sum = write_import(rec, o);
    }
    EXPECT_EQ(sum.skipped, 0u);
    EXPECT_EQ(sum.info.point_times, io::PointTimes::kSensor);
    const fs::path a = root_ / "source" / "robot_0", b = o.out / "robot_0";
    const std::vector<int64_t> ta = geometry::read_times((a / "times.txt").string());
    const std::vector<int64_t> tb = geometry::read_times((b / "times.txt").string());
    ASSERT_EQ(ta.size(), tb.size());
    const int64_t shift = ta[0] - tb[0];  // the import's clock starts at the first sample
    for (size_t k = 0; k < ta.size(); ++k) {
      EXPECT_EQ(tb[k] + shift, ta[k]) << "sweep " << k;
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.bin", k);
      EXPECT_EQ(read_file(b / "velodyne" / name), read_file(a / "velodyne" / name)) << "sweep " << k;
      EXPECT_EQ(read_file(b / "velodyne_meta" / name), read_file(a / "velodyne_meta" / name)) << "sweep " << k;
    }
    const auto ia = io::read_dataset_imu(a / "imu.csv");
    const auto ib = io::read_dataset_imu(b / "imu.csv");
    ASSERT_EQ(ib.size(), ia.size());
    for (size_t i = 0; i < ib.size(); ++i) {
      EXPECT_EQ(ib[i].stamp_ns + shift, ia[i].stamp_ns);
      EXPECT_LT((ib[i].accel - ia[i].accel).norm(), 1e-9);
      EXPECT_LT((ib[i].gyro - ia[i].gyro).norm(), 1e-9);
    }
    EXPECT_FALSE(fs::exists(root_ / "imported.extract")) << "the scratch folder outlives the import";
  }

  fs::path root_;
};

TEST_F(ImportBag, Ros1BagRoundTripsSweepsTimesAndImu) { expect_round_trip(write_bag("ros1")); }
TEST_F(ImportBag, Ros2Db3BagRoundTripsSweepsTimesAndImu) { expect_round_trip(write_bag("db3")); }
TEST_F(ImportBag, McapRoundTripsSweepsTimesAndImu) { expect_round_trip(write_bag("mcap")); }

TEST_F(ImportBag, ATruncatedBagIsRefusedNamingTheFileAndNothingIsWritten) {
  const fs::path bag = write_bag("ros1");
  const std::string bytes = read_file(bag);
  const fs::path cut = root_ / "cut.bag";
  std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() * 2 / 3);
  try {
    const Recording rec = bag_recording(cut, {}, root_ / "out.extract");
    FAIL() << "a truncated bag was imported";
  } catch (const io::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.bag"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(root_ / "out.extract"));
  EXPECT_FALSE(fs::exists(root_ / "out"));
}

TEST_F(ImportBag, ACloudWithAWrongFieldLayoutIsSkippedCountedAndNamed) {
  const fs::path bag = write_bag("ros1", " --bad-cloud 2");
  ImportOptions o;
  o.out = root_ / "imported";
  ImportSummary sum;
  {
    const Recording rec = bag_recording(bag, {}, root_ / "imported.extract");
    sum = write_import(rec, o);
  }
  EXPECT_EQ(sum.skipped, 1u);
  EXPECT_EQ(sum.info.scans, 3u);
  bool named = false;
  for (const std::string& n : sum.notes)
    named = named || (n.find("skipped 1 x") != std::string::npos && n.find("time") != std::string::npos);
  EXPECT_TRUE(named) << "no note names the skipped cloud's bad field";
  // The sweeps that did decode are the source's sweeps 0, 1 and 3.
  const std::vector<int64_t> ta = geometry::read_times((root_ / "source" / "robot_0" / "times.txt").string());
  const std::vector<int64_t> tb = geometry::read_times((o.out / "robot_0" / "times.txt").string());
  ASSERT_EQ(tb.size(), 3u);
  EXPECT_EQ(tb[2] - tb[1], ta[3] - ta[1]);
  EXPECT_EQ(read_file(o.out / "robot_0" / "velodyne" / "000002.bin"),
            read_file(root_ / "source" / "robot_0" / "velodyne" / "000003.bin"));
}

TEST_F(ImportBag, ATopicOfAnotherTypeIsRefusedByName) {
  const fs::path bag = write_bag("mcap");
  BagImportOptions o;
  o.lidar_topic = "/imu";
  try {
    bag_recording(bag, o, root_ / "out.extract");
    FAIL() << "an Imu topic was taken for a LiDAR topic";
  } catch (const io::FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("sensor_msgs/msg/Imu"), std::string::npos) << e.what();
  }
  o.lidar_topic = "/nothing";
  EXPECT_THROW(bag_recording(bag, o, root_ / "out.extract"), io::FormatError);
}

}  // namespace
}  // namespace cdc::sim
