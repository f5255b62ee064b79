// A front-end restarted while its back-end runs (loopback configuration, real processes): the swarm
// feeder stands in for robot 0's front-end, is SIGKILLed in mid-drive and started again as a
// restarted front-end starts (continuing the keyframe sequence its peer optimiser holds). Every
// keyframe of both front-ends reaches the peer optimiser and the central exactly once, as one
// sequence, nothing is refused, and the peer's --trajectory-out has strictly increasing stamps.
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/graph/g2o.hpp"
#include "child_process.hpp"
#include "process_test.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <thread>

namespace cdc {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

constexpr uint32_t kKeyframes = 120;

void stop(test::ChildProcess& p) { p.stop(10s); }

nlohmann::json json_of(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

class FrontendRestart : public test::ProcessTest {
 protected:
  FrontendRestart() : ProcessTest("frontend_restart", {"CDC_CENTRAL_BIN", "CDC_PEER_BIN", "CDC_FEEDER_BIN"}) {}

  void set_up() override {
    t_sequence_ = std::make_unique<dds::Topic<cdc_msg_KeyframeSequence>>(*participant_, dds::topics::kKeyframeSequence);
    r_sequence_ = std::make_unique<dds::Reader<cdc_msg_KeyframeSequence>>(
        *participant_, *t_sequence_, dds::qos::keyed_state().partitions(dds::partitions::all_robots_reader()));
  }

  void stop_processes() override {
    for (auto* p : {&feeder_, &peer_, &central_}) stop(*p);
  }

  void start_feeder(const std::string& tag, std::vector<std::string> extra) {
    std::vector<std::string> args{std::getenv("CDC_FEEDER_BIN"), "--robots",       "1", "--keyframes",
                                  std::to_string(kKeyframes),    "--wait-readers", "2"};
    args.insert(args.end(), extra.begin(), extra.end());
    feeder_ = test::ChildProcess::spawn(args, path("feeder_" + tag + ".log"));
  }

  // The newest keyframe the peer optimiser holds, as it last said (-1: none yet).
  int64_t newest_held() {
    r_sequence_->take(16).for_each_valid([&](const cdc_msg_KeyframeSequence& m, const dds_sample_info_t&) {
      if (m.robot_id == 0) newest_ = m.newest_keyframe_id;
    });
    return newest_;
  }

  bool wait_newest_at_least(int64_t id, std::chrono::milliseconds timeout) {
    for (auto until = std::chrono::steady_clock::now() + timeout; std::chrono::steady_clock::now() < until;) {
      if (newest_held() >= id) return true;
      std::this_thread::sleep_for(20ms);
    }
    return false;
  }

  std::unique_ptr<dds::Topic<cdc_msg_KeyframeSequence>> t_sequence_;
  std::unique_ptr<dds::Reader<cdc_msg_KeyframeSequence>> r_sequence_;
  test::ChildProcess central_, peer_, feeder_;
  int64_t newest_ = -1;
};

TEST_F(FrontendRestart, EveryKeyframeOfBothFrontEndsReachesPeerAndCentralOnce) {
  std::ofstream(path("central.yaml")) << "robots: 1\nlease_ms: 1000\n";
  std::ofstream(path("peer.yaml")) << "robots: 1\nrange_m: 1.0e6\ndwell_ms: 500\nmask_ms: 500\n";
  central_ = test::ChildProcess::spawn({std::getenv("CDC_CENTRAL_BIN"), "--config", path("central.yaml"), "--stats-out",
                                        path("central.json"), "--graph-out", path("central.g2o")},
                                       path("central.log"));
  peer_ = test::ChildProcess::spawn({std::getenv("CDC_PEER_BIN"), "--robot", "0", "--config", path("peer.yaml"),
                                     "--stats-out", path("peer.json"), "--trajectory-out", path("peer.tum")},
                                    path("peer.log"));
  start_feeder("first", {"--rate-hz", "25", "--incarnation", "4242"});
  ASSERT_TRUE(wait_newest_at_least(50, 30s)) << "the first front-end's keyframes never reached the peer";
  feeder_.signal(SIGKILL);  // in mid-drive
  ASSERT_TRUE(feeder_.wait(5s));
  std::this_thread::sleep_for(200ms);
  const int64_t before_restart = newest_held();

  // The restarted front-end's sweeps come with a new incarnation; its keyframes continue the sequence.
  start_feeder("restarted", {"--rate-hz", "40", "--incarnation", "4243", "--continue-wait-ms", "5000"});
  const auto fs_ = feeder_.wait(30s);
  ASSERT_TRUE(fs_ && WIFEXITED(*fs_) && WEXITSTATUS(*fs_) == 0) << "see " << path("feeder_restarted.log");
  EXPECT_NE(test::read_file(path("feeder_restarted.log"))
                .find("robot 0 continues its back-end's sequence, from keyframe " + std::to_string(before_restart + 1) +
                      " of incarnation 4242"),
            std::string::npos)
      << "the restarted front-end did not continue after keyframe " << before_restart;
  ASSERT_TRUE(wait_newest_at_least(kKeyframes - 1, 10s)) << "the peer holds up to " << newest_held();
  std::this_thread::sleep_for(2s);  // the central's last updates and acknowledgements
  stop(peer_);
  stop(central_);

  const nlohmann::json peer = json_of(path("peer.json"));
  EXPECT_EQ(peer["keyframes"].get<uint32_t>(), kKeyframes);
  EXPECT_EQ(peer["keyframes_refused"].get<int>(), 0);
  EXPECT_FALSE(peer["rejected"].contains(dds::topics::kKeyframe)) << peer["rejected"].dump();
  const nlohmann::json central = json_of(path("central.json"));
  EXPECT_EQ(central["keyframes_rejected"].get<int>(), 0);
  ASSERT_EQ(central["sessions"].size(), 1u) << central["sessions"].dump();
  EXPECT_EQ(central["sessions"][0]["incarnation"].get<uint32_t>(), 4242u);
  EXPECT_EQ(central["sessions"][0]["keyframes_held"].get<uint32_t>(), kKeyframes);
  EXPECT_EQ(central["sessions"][0]["highest_contiguous_keyframe"].get<int64_t>(), int64_t{kKeyframes} - 1);

  // One chain in the central's graph: keyframes 0..119 of robot 0's one session, 119 odometry factors.
  const graph::PoseGraph g = graph::read_g2o(path("central.g2o"));
  std::set<uint64_t> ids;
  for (const auto& [key, T] : g.poses) {
    EXPECT_EQ(graph::robot_of(key), 0u);
    ids.insert(graph::index_of(key));
  }
  EXPECT_EQ(ids.size(), kKeyframes);
  EXPECT_EQ(*ids.rbegin(), kKeyframes - 1) << "keys of one session, ids 0.." << kKeyframes - 1;
  EXPECT_EQ(g.count(graph::FactorKind::kOdometry), kKeyframes - 1);

  const geometry::Trajectory t = geometry::read_tum(path("peer.tum"));
  ASSERT_EQ(t.size(), kKeyframes);
  for (size_t i = 1; i < t.size(); ++i) EXPECT_GT(t[i].stamp_ns, t[i - 1].stamp_ns) << "line " << i + 1;
}

}  // namespace
}  // namespace cdc
