// cdc-frontend over DDS with real processes (loopback configuration): a simulated drive played
// in lock-step by cdc-sim (sweeps with motion distortion, IMU), the front-end's odometry and
// keyframes received by the test; malformed and out-of-order sweeps are rejected and counted
// without disturbing it.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "child_process.hpp"
#include "process_test.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>
#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <thread>

namespace cdc {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

class FrontendService : public test::ProcessTest {
 protected:
  FrontendService() : ProcessTest("frontend_service", {"CDC_FRONTEND_BIN", "CDC_SIM_BIN"}) {}
};

TEST_F(FrontendService, OdometryAndKeyframesFromAPlayedDrive) {
  const fs::path& dir = dir_;
  std::ofstream(dir / "drive.yaml")
      << "name: drive\nseed: 4\ntrajectories:\n  source: procedural\n  pattern: crossing\n"
         "  robots: 1\n  speed_mps: 6\n  size_m: 80\n  duration_s: 16\nlidar: vlp16\n";
  std::ofstream(dir / "frontend.yaml") << "robots: 1\n";
  test::ChildProcess gen = test::ChildProcess::spawn({std::getenv("CDC_SIM_BIN"), "generate", "--scenario",
                                                      (dir / "drive.yaml").string(), "--out", (dir / "ds").string()},
                                                     (dir / "generate.log").string());
  const auto gs = gen.wait(120s);
  ASSERT_TRUE(gs && WIFEXITED(*gs) && WEXITSTATUS(*gs) == 0) << "see " << dir / "generate.log";

  dds::Participant& participant = *participant_;
  dds::Topic<cdc_msg_LidarScan> t_scan(participant, dds::topics::kLidar);
  dds::Topic<cdc_msg_Keyframe> t_kf(participant, dds::topics::kKeyframe);
  dds::Writer<cdc_msg_LidarScan> w_scan(participant, t_scan, dds::qos::sensor_stream(16, true));
  // The front-end writes its keyframes in its robot's partition, as the central node reads them.
  dds::Reader<cdc_msg_Keyframe> r_kf(participant, t_kf,
                                     dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader()));

  test::ChildProcess fe = test::ChildProcess::spawn(
      {std::getenv("CDC_FRONTEND_BIN"), "--robot", "0", "--config", (dir / "frontend.yaml").string(), "--stats-out",
       (dir / "stats.json").string(), "--trajectory-out", (dir / "odometry.tum").string(),
       // Lock-step playback, as cdc-launch runs it: every sweep waits for its IMU however busy the machine is.
       "--imu-wait-ms", "5000"},
      (dir / "frontend.log").string());
  ASSERT_TRUE(w_scan.wait_for_readers(1, 15s));
  auto bad_scan = [&](int64_t stamp, uint32_t n, bool nan) {
    std::vector<cdc_msg_LidarPoint> pts(n, cdc_msg_LidarPoint{5.0f, 1.0f, 0.5f, 0.5f, 0.01f, 3});
    if (nan && n > 0) pts[n / 2].y = std::nanf("");
    cdc_msg_LidarScan m{};
    m.robot_id = 0;
    m.seq = 999999;
    m.stamp_ns = stamp;
    m.duration_ns = 100'000'000;
    m.point_count = n;
    dds::borrow(m.points, pts);
    w_scan.write(m);
  };
  bad_scan(1, 1000, true);  // a NaN point
  bad_scan(2, 0, false);    // an empty sweep

  test::ChildProcess player = test::ChildProcess::spawn(
      {std::getenv("CDC_SIM_BIN"), "play", (dir / "ds").string(), "--lockstep", "--wait-readers", "1"},
      (dir / "player.log").string());
  size_t keyframes = 0;
  std::optional<int> ps;
  for (int i = 0; i < 1200 && !ps; ++i) {
    r_kf.take(256).for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
      EXPECT_EQ(m.keyframe_id, keyframes);
      EXPECT_EQ(m.point_count, m.cloud._length);
      ++keyframes;
    });
    ps = player.wait(100ms);
  }
  ASSERT_TRUE(ps && WIFEXITED(*ps) && WEXITSTATUS(*ps) == 0) << "player failed, see " << dir / "player.log";
  bad_scan(3, 1000, false);  // out of order: older than every played sweep
  std::this_thread::sleep_for(1s);
  r_kf.take(256).for_each_valid([&](const cdc_msg_Keyframe&, const dds_sample_info_t&) { ++keyframes; });
  fe.signal(SIGTERM);
  const auto fs_ = fe.wait(10s);
  ASSERT_TRUE(fs_ && WIFEXITED(*fs_) && WEXITSTATUS(*fs_) == 0);

  std::ifstream sin(dir / "stats.json");
  const nlohmann::json st = nlohmann::json::parse(sin);
  const geometry::Trajectory gt = geometry::read_tum((dir / "ds" / "robot_0" / "groundtruth.tum").string());
  const geometry::Trajectory est = geometry::read_tum((dir / "odometry.tum").string());
  EXPECT_EQ(st["scans"].get<size_t>(), gt.size()) << "every played sweep processed";
  EXPECT_EQ(st["rejected"][dds::topics::kLidar].get<int>(), 3);
  EXPECT_EQ(st["keyframes"].get<size_t>(), keyframes);
  EXPECT_GT(st["imu_samples"].get<int>(), 1000);
  EXPECT_EQ(st["imu_late"].get<int>(), 0) << "a sweep went ahead without its IMU";
  // The IMU window runs after its 3 s gravity alignment and predicts the sweeps from then on.
  EXPECT_GT(st["imu_predictions"].get<size_t>(), gt.size() / 2);
  EXPECT_EQ(st["imu_predictions_rejected"].get<int>(), 0);
  EXPECT_GT(keyframes, 60u);  // a keyframe per metre of ~90 m
  // The odometry against the ground truth (both from the first sweep's pose).
  geometry::Poses a, b;
  for (size_t i = 0; i < est.size() && i < gt.size(); ++i) {
    ASSERT_EQ(est[i].stamp_ns, gt[i].stamp_ns);
    a.push_back(est[i].pose);
    b.push_back(gt.front().pose.inverse() * gt[i].pose);
  }
  const geometry::AteResult ate = geometry::compute_ate(a, b, geometry::AlignMode::kNone);
  std::printf("%zu sweeps, %zu keyframes, ATE %.3f m (max %.3f m)\n", a.size(), keyframes, ate.translation.rmse,
              ate.translation.max);
  EXPECT_LT(ate.translation.max, 0.3);
  std::ifstream log(dir / "frontend.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("non-finite value"), std::string::npos);
  EXPECT_NE(text.find("empty sweep"), std::string::npos);
  EXPECT_NE(text.find("out of order"), std::string::npos);
}

}  // namespace
}  // namespace cdc
