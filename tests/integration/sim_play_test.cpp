// cdc-sim play over DDS: lock-step delivers every scan of every robot exactly once and in order to
// a (slow) consumer; the KITTI player publishes real scans with their ground truth.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/io/kitti.hpp"
#include "child_process.hpp"
#include "process_test.hpp"
#include "scenario.hpp"

#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

namespace cdc {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

class SimPlay : public test::ProcessTest {
 protected:
  SimPlay() : ProcessTest("sim_play", {"CDC_SIM_BIN"}) {}

  void set_up() override {
    t_lidar_ = std::make_unique<dds::Topic<cdc_msg_LidarScan>>(*participant_, dds::topics::kLidar);
    t_gt_ = std::make_unique<dds::Topic<cdc_msg_GroundTruth>>(*participant_, dds::topics::kGroundTruth);
    t_progress_ = std::make_unique<dds::Topic<cdc_msg_ConsumerProgress>>(*participant_, dds::topics::kProgress);
    r_lidar_ =
        std::make_unique<dds::Reader<cdc_msg_LidarScan>>(*participant_, *t_lidar_, dds::qos::sensor_stream(16, true));
    dds::Qos gt_qos;
    gt_qos.reliable().keep_last(4096).transient_local();
    r_gt_ = std::make_unique<dds::Reader<cdc_msg_GroundTruth>>(*participant_, *t_gt_, gt_qos);
    t_radio_ = std::make_unique<dds::Topic<cdc_msg_RadioState>>(*participant_, dds::topics::kRadio);
    r_radio_ =
        std::make_unique<dds::Reader<cdc_msg_RadioState>>(*participant_, *t_radio_, dds::qos::event_stream(1024));
    w_progress_ =
        std::make_unique<dds::Writer<cdc_msg_ConsumerProgress>>(*participant_, *t_progress_, dds::qos::keyed_state());
  }
  // A two-robot procedural scenario's dataset in dir_/ds, max_scans sweeps per robot.
  sim::GenerateSummary generate_small(size_t max_scans) {
    const fs::path sc = dir_ / "small.yaml";
    std::ofstream(sc) << "name: small\nseed: 5\ntrajectories:\n  source: procedural\n  pattern: loops\n  robots: 2\n"
                         "  duration_s: 10\n  size_m: 40\nradio:\n  central_robot: 0\n";
    sim::GenerateOptions g;
    g.max_scans = max_scans;
    return sim::generate_dataset(sim::load_scenario(sc.string()), sc.string(), path("ds"), g);
  }

  std::unique_ptr<dds::Topic<cdc_msg_LidarScan>> t_lidar_;
  std::unique_ptr<dds::Topic<cdc_msg_GroundTruth>> t_gt_;
  std::unique_ptr<dds::Topic<cdc_msg_ConsumerProgress>> t_progress_;
  std::unique_ptr<dds::Reader<cdc_msg_LidarScan>> r_lidar_;
  std::unique_ptr<dds::Reader<cdc_msg_GroundTruth>> r_gt_;
  std::unique_ptr<dds::Writer<cdc_msg_ConsumerProgress>> w_progress_;
  std::unique_ptr<dds::Topic<cdc_msg_RadioState>> t_radio_;
  std::unique_ptr<dds::Reader<cdc_msg_RadioState>> r_radio_;
};

TEST_F(SimPlay, LockStepDeliversEveryScanExactlyOnceInOrder) {
  ASSERT_EQ(generate_small(25).scans, 50u);

  test::ChildProcess player = test::ChildProcess::spawn(
      {std::getenv("CDC_SIM_BIN"), "play", path("ds"), "--lockstep", "--wait-readers", "1"}, path("player.log"));
  std::map<uint32_t, std::vector<uint64_t>> seen;
  std::map<uint32_t, std::vector<uint32_t>> counts;
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  size_t total = 0;
  while (total < 50 && std::chrono::steady_clock::now() < deadline) {
    r_lidar_->take(16).for_each_valid([&](const cdc_msg_LidarScan& s, const dds_sample_info_t&) {
      seen[s.robot_id].push_back(s.seq);
      counts[s.robot_id].push_back(s.point_count);
      ++total;
      std::this_thread::sleep_for(5ms);  // a slow front-end
      cdc_msg_ConsumerProgress p{};
      p.robot_id = s.robot_id;
      p.last_scan_seq = s.seq;
      w_progress_->write(p);
    });
    std::this_thread::sleep_for(1ms);
  }
  const auto st = player.wait(20s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << "player failed, see " << (dir_ / "player.log");
  size_t radio_states = 0, links = 0;
  r_radio_->take(1024).for_each_valid([&](const cdc_msg_RadioState& m, const dds_sample_info_t&) {
    ++radio_states;
    links += m.links._length;
  });
  EXPECT_GT(radio_states, 10u) << "no radio timeline on cdc/sim/radio";
  EXPECT_EQ(links, radio_states * 3u);  // two robots and the central: three links per instant
  std::vector<uint64_t> expected(25);
  for (uint64_t i = 0; i < 25; ++i) expected[i] = i;
  for (uint32_t r = 0; r < 2; ++r) {
    EXPECT_EQ(seen[r], expected) << "robot " << r;
    for (size_t k = 0; k < counts[r].size(); ++k) {
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.bin", k);
      EXPECT_EQ(counts[r][k] * 16u, fs::file_size(dir_ / "ds" / ("robot_" + std::to_string(r)) / "velodyne" / name));
    }
  }
}

TEST_F(SimPlay, APlayerBesideARobotPlaysOnlyThatRobot) {
  generate_small(10);
  test::ChildProcess player = test::ChildProcess::spawn(
      {std::getenv("CDC_SIM_BIN"), "play", path("ds"), "--robot", "1", "--lockstep", "--wait-readers", "1"},
      path("player.log"));
  std::map<uint32_t, size_t> per_robot;
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while (per_robot[1] < 10 && std::chrono::steady_clock::now() < deadline) {
    r_lidar_->take(16).for_each_valid([&](const cdc_msg_LidarScan& s, const dds_sample_info_t&) {
      ++per_robot[s.robot_id];
      w_progress_->write(cdc_msg_ConsumerProgress{s.robot_id, s.incarnation, s.seq});
    });
    std::this_thread::sleep_for(1ms);
  }
  const auto st = player.wait(20s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << "player failed, see " << (dir_ / "player.log");
  r_lidar_->take(64).for_each_valid(
      [&](const cdc_msg_LidarScan& s, const dds_sample_info_t&) { ++per_robot[s.robot_id]; });
  EXPECT_EQ(per_robot[1], 10u);
  EXPECT_EQ(per_robot[0], 0u) << "robot 0's sweeps were played too";
  // A robot the dataset does not have is named.
  test::ChildProcess bad =
      test::ChildProcess::spawn({std::getenv("CDC_SIM_BIN"), "play", path("ds"), "--robot", "7"}, path("bad.log"));
  const auto bs = bad.wait(20s);
  ASSERT_TRUE(bs && WIFEXITED(*bs));
  EXPECT_NE(WEXITSTATUS(*bs), 0);
  std::ifstream log(dir_ / "bad.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("no scans of robot 7"), std::string::npos) << text;
}

TEST_F(SimPlay, ImportedKittiSweepsPlayWithTheirGroundTruthAndNoInventedTimes) {
  const char* env = std::getenv("CDC_DATA_DIR");
  const fs::path data = env != nullptr ? env : "../shared/data";
  if (!fs::exists(data / "kitti/scans/seq00")) {
    GTEST_SKIP() << "reference data absent: " << (data / "kitti/scans/seq00") << " not found";
  }
  test::ChildProcess import = test::ChildProcess::spawn(
      {std::getenv("CDC_IMPORT_BIN"), "kitti", (data / "kitti/scans/seq00").string(), "--allow-gaps", "--poses",
       (data / "kitti/poses/00.txt").string(), "--calib", (data / "kitti/calib_Tr.txt").string(), "--calib-key",
       "Tr_00_02", "--out", path("seq00")},
      path("import.log"));
  const auto is = import.wait(60s);
  ASSERT_TRUE(is && WIFEXITED(*is) && WEXITSTATUS(*is) == 0) << "cdc-import failed: see " << (dir_ / "import.log");
  test::ChildProcess player = test::ChildProcess::spawn(
      {std::getenv("CDC_SIM_BIN"), "play", path("seq00"), "--rate", "0", "--wait-readers", "1"}, path("player.log"));
  std::vector<cdc_msg_LidarScan> scans;
  std::map<int64_t, Eigen::Isometry3d> truth;
  const auto deadline = std::chrono::steady_clock::now() + 30s;
  while ((scans.size() < 4 || truth.size() < 4) && std::chrono::steady_clock::now() < deadline) {
    r_lidar_->take(16).for_each_valid([&](const cdc_msg_LidarScan& s, const dds_sample_info_t&) {
      cdc_msg_LidarScan head = s;
      bool all_zero = true;
      for (uint32_t i = 0; i < s.points._length; ++i) all_zero = all_zero && s.points._buffer[i].time_offset == 0.0f;
      EXPECT_TRUE(all_zero) << "a KITTI sweep imported as motion-compensated carries invented point times";
      head.points = {};
      scans.push_back(head);
    });
    r_gt_->take(16).for_each_valid([&](const cdc_msg_GroundTruth& g, const dds_sample_info_t&) {
      truth[g.stamp_ns] = dds::to_eigen(g.T_world_base);
    });
    std::this_thread::sleep_for(2ms);
  }
  const auto st = player.wait(20s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0);
  ASSERT_EQ(scans.size(), 4u);
  const auto seq = io::kitti_lidar_trajectory((data / "kitti/poses/00.txt").string(),
                                              io::read_kitti_calib((data / "kitti/calib_Tr.txt").string(), "Tr_00_02"));
  const int frames[4] = {94, 95, 198, 199};
  for (int i = 0; i < 4; ++i) {
    const int64_t stamp = (frames[i] - frames[0]) * 100'000'000LL;  // the import's clock starts at the first sweep
    EXPECT_EQ(scans[static_cast<size_t>(i)].stamp_ns, stamp);
    EXPECT_EQ(scans[static_cast<size_t>(i)].duration_ns, 0) << "a motion-compensated sweep has no duration";
    char name[32];
    std::snprintf(name, sizeof name, "%06d.bin", frames[i]);
    EXPECT_EQ(scans[static_cast<size_t>(i)].point_count * 16u, fs::file_size(data / "kitti/scans/seq00" / name));
    const auto it = truth.find(stamp);
    ASSERT_NE(it, truth.end());
    EXPECT_LT((it->second.matrix() - seq[static_cast<size_t>(frames[i])].pose.matrix()).norm(), 1e-6);
  }
}

TEST_F(SimPlay, AMissingFolderIsNamed) {
  test::ChildProcess player =
      test::ChildProcess::spawn({std::getenv("CDC_SIM_BIN"), "play", path("nothing")}, path("player.log"));
  const auto st = player.wait(10s);
  ASSERT_TRUE(st && WIFEXITED(*st));
  EXPECT_EQ(WEXITSTATUS(*st), 1);
  std::ifstream log(dir_ / "player.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find(path("nothing")), std::string::npos) << text;
}

}  // namespace
}  // namespace cdc
