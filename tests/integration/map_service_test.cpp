// cdc-map over DDS (loopback configuration): packed keyframe clouds of two robots and the central's
// poses in; SIGUSR1 writes the map while it runs, malformed clouds are rejected and counted, and
// SIGTERM writes it again and exits cleanly.
#include "cdc/dds/compact.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
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

class MapService : public test::ProcessTest {
 protected:
  MapService() : ProcessTest("map_service", {"CDC_MAP_BIN"}) {}
};

TEST_F(MapService, BuildsAndWritesTheMapFromKeyframesAndCentralPoses) {
  const fs::path& dir = dir_;
  std::ofstream(dir / "map.yaml") << "robots: 2\n";
  dds::Participant& participant = *participant_;
  dds::Topic<cdc_msg_KeyframeCloud> t_kf(participant, dds::topics::kKeyframeCloud);
  dds::Topic<cdc_msg_OptimizedPoses> t_opt(participant, dds::topics::kCentralOptimized);
  dds::Writer<cdc_msg_KeyframeCloud> w_kf(participant, t_kf, dds::qos::event_stream(4096));
  dds::Writer<cdc_msg_OptimizedPoses> w_opt(participant, t_opt, dds::qos::monitored_writer(std::chrono::seconds(1)));
  test::ChildProcess map =
      test::ChildProcess::spawn({std::getenv("CDC_MAP_BIN"), "--config", (dir / "map.yaml").string(), "--out",
                                 (dir / "out").string(), "--stats-out", (dir / "stats.json").string()},
                                (dir / "map.log").string());
  ASSERT_TRUE(w_kf.wait_for_readers(1, 15s));
  ASSERT_TRUE(w_opt.wait_for_readers(1, 15s));
  // Each keyframe: a 10 x 6 m wall of points 5 m ahead, 1,000 points, packed on a 2 cm grid.
  std::vector<Eigen::Vector3f> cloud;
  for (int i = 0; i < 40; ++i) {
    for (int j = 0; j < 25; ++j)
      cloud.emplace_back(5.0f, -5.0f + 0.25f * static_cast<float>(i), -2.0f + 0.25f * static_cast<float>(j));
  }
  dds::compact::PackedCloud packed = dds::compact::pack_points(cloud, 0.02f);
  ASSERT_EQ(packed.count, 1000u);
  auto cloud_message = [&](uint32_t robot, uint32_t keyframe) {
    cdc_msg_KeyframeCloud m{};
    m.robot_id = robot;
    m.keyframe_id = keyframe;
    m.point_count = packed.count;
    m.resolution_m = packed.resolution_m;
    dds::borrow(m.packed_points, packed.bytes);
    return m;
  };
  for (uint32_t r = 0; r < 2; ++r) {
    for (uint32_t k = 0; k < 5; ++k) w_kf.write(cloud_message(r, k));
  }
  {
    cdc_msg_KeyframeCloud bad = cloud_message(0, 77);  // a point count that disagrees with the packed bytes
    bad.point_count = 3;
    w_kf.write(bad);
    std::vector<uint8_t> corrupt = packed.bytes;  // bytes that do not inflate
    for (size_t i = 2; i < corrupt.size(); i += 5) corrupt[i] ^= 0x5A;
    bad = cloud_message(1, 78);
    dds::borrow(bad.packed_points, corrupt);
    w_kf.write(bad);
  }
  std::vector<cdc_msg_KeyframePose> poses;
  for (uint32_t r = 0; r < 2; ++r) {
    poses.clear();
    for (uint32_t k = 0; k < 5; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = Eigen::Vector3d(20.0 * r, 12.0 * k, 0);
      poses.push_back(cdc_msg_KeyframePose{r, k, dds::to_msg(T)});
    }
    cdc_msg_OptimizedPoses m{};
    m.robot_id = r;
    m.sender_robot_id = 200;
    m.graph_version = 1;
    m.source = cdc_msg_SOURCE_CENTRAL;
    m.T_world_robot = dds::to_msg(Eigen::Isometry3d::Identity());
    dds::borrow(m.poses, poses);
    w_opt.write(m);
  }
  std::this_thread::sleep_for(1500ms);
  map.signal(SIGUSR1);
  for (int i = 0; i < 50 && !fs::exists(dir / "out" / "map.bt"); ++i) std::this_thread::sleep_for(100ms);
  EXPECT_TRUE(fs::exists(dir / "out" / "map.pcd"));
  EXPECT_TRUE(fs::exists(dir / "out" / "map.bt"));
  map.signal(SIGTERM);
  const auto st = map.wait(10s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << "see " << dir / "map.log";
  std::ifstream sin(dir / "stats.json");
  const nlohmann::json s = nlohmann::json::parse(sin);
  EXPECT_EQ(s["keyframes"].get<int>(), 10);
  EXPECT_EQ(s["placed"].get<int>(), 10);
  EXPECT_EQ(s["writes"].get<int>(), 2) << "one on SIGUSR1, one at shutdown";
  EXPECT_EQ(s["rejected"][dds::topics::kKeyframeCloud].get<int>(), 2);
  // 10 walls of 10 x 6 m, disjoint: 10 x 40 x 25 points survive the 0.2 m voxel filter.
  std::ifstream pcd(dir / "out" / "map.pcd", std::ios::binary);
  std::string line;
  size_t points = 0;
  while (std::getline(pcd, line) && line != "DATA binary") {
    if (line.rfind("POINTS ", 0) == 0) points = std::stoul(line.substr(7));
  }
  EXPECT_EQ(points, 10u * 1000u);
}

}  // namespace
}  // namespace cdc
