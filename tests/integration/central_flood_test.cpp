// The central optimiser against a hostile writer, with real processes over DDS (loopback): a central,
// three peer optimisers fed by the swarm feeder, and, from this process, 60,000 keyframes of robot 1
// whose ids never become contiguous (1,000,000, 1,000,002, ...), in a partition only the central reads.
//  * The central's liveliness never lapses and no robot logs a mode switch while the flood runs.
//  * Every hostile sample is counted in the central's stats: held as pending (at most the cap),
//    refused at the cap, or lost or refused by its reader; every robot's own keyframe is in the graph.
// And a central whose host robot is not in the world yet says it knows no world, rather than placing
// itself at the origin.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/liveliness.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
#include "child_process.hpp"
#include "dds_helpers.hpp"
#include "process_test.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>
#include <csignal>
#include <cstdlib>
#include <deque>
#include <map>
#include <sstream>
#include <thread>

namespace cdc {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

constexpr uint32_t kRobots = 3, kKeyframes = 300, kFlood = 60'000;
constexpr uint32_t kFeederIncarnation = 4242;  // cdc-test-swarm-feeder's default

class CentralUnderAttack : public test::ProcessTest {
 protected:
  CentralUnderAttack() : ProcessTest("central_flood", {"CDC_CENTRAL_BIN", "CDC_PEER_BIN", "CDC_FEEDER_BIN"}) {}

  void stop_processes() override {
    for (auto it = children_.rbegin(); it != children_.rend(); ++it) end(*it);
  }

  // SIGTERM, then SIGKILL if it does not stop; true when it exited with status 0.
  static bool end(test::ChildProcess& p) {
    if (!p.running()) return true;
    const auto st = p.stop(20s);
    return st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0;
  }

  test::ChildProcess& spawn(const char* binary_env, std::vector<std::string> args, const std::string& log) {
    args.insert(args.begin(), std::getenv(binary_env));
    children_.push_back(test::ChildProcess::spawn(args, path(log)));
    return children_.back();
  }
  test::ChildProcess& start_central(const std::string& config) {
    return spawn("CDC_CENTRAL_BIN", {"--config", config, "--stats-out", path("central.json")}, "central.log");
  }
  std::string read(const std::string& name) const { return test::read_file(path(name)); }

  std::deque<test::ChildProcess> children_;  // started in this order, ended in reverse
};

size_t count_lines_with(const std::string& text, const std::string& what) {
  std::istringstream in(text);
  size_t n = 0;
  for (std::string line; std::getline(in, line);) {
    if (line.find(what) != std::string::npos) ++n;
  }
  return n;
}

// Writes kFlood keyframes of robot 1 whose ids never become contiguous, retrying a write the
// reliable writer could not place in time (the central reads at its own pace); returns seconds taken.
double flood(const dds::Participant& participant) {
  dds::Topic<cdc_msg_Keyframe> topic(participant, dds::topics::kKeyframe);
  // robot/99 matches the central's robot/* and no peer's partition.
  dds::Writer<cdc_msg_Keyframe> w(participant, topic, dds::qos::event_stream(4096).partitions({"robot/99"}));
  EXPECT_TRUE(w.wait_for_readers(1, 10s));
  cdc_msg_Keyframe m{};
  m.robot_id = 1;
  m.incarnation = kFeederIncarnation;
  m.T_odom_keyframe = dds::to_msg(Eigen::Isometry3d::Identity());
  m.T_prev_keyframe = m.T_odom_keyframe;
  dds::information_to_msg(Eigen::Matrix<double, 6, 6>::Identity(), m.information);
  const auto t0 = Clock::now();
  uint32_t retries = 0;
  for (uint32_t i = 0; i < kFlood;) {
    m.keyframe_id = 1'000'000 + 2 * i;
    m.stamp_ns = dds::now_ns();
    try {
      w.write(m);
      ++i;
    } catch (const dds::DdsError&) {
      ++retries;  // the writer's history is full until the central acknowledges
    }
  }
  const double s = std::chrono::duration<double>(Clock::now() - t0).count();
  std::printf("flood: %u keyframes written in %.2f s (%u writes retried)\n", kFlood, s, retries);
  return s;
}

TEST_F(CentralUnderAttack, AKeyframeFloodNeitherStallsTheCentralNorGoesUncounted) {
  const std::string central_cfg = write("central.yaml", "robots: 3\nlease_ms: 1000\n");
  const std::string peer_cfg = write("peer.yaml", "robots: 3\nrange_m: 1.0e6\ndwell_ms: 1000\nmask_ms: 1000\n");
  dds::Topic<cdc_msg_RobotStatus> t_alive(*participant_, dds::topics::kCentralAlive);
  dds::LivelinessMonitor central_alive(*participant_, t_alive.handle(), "central");
  dds::Topic<cdc_msg_ModeState> t_mode(*participant_, dds::topics::kMode);
  dds::Qos deep;
  deep.reliable().keep_last(4096).transient_local();
  dds::Reader<cdc_msg_ModeState> modes(*participant_, t_mode, deep);
  test::ChildProcess& central = start_central(central_cfg);
  std::vector<test::ChildProcess*> peers;
  for (uint32_t r = 0; r < kRobots; ++r) {
    peers.push_back(&spawn("CDC_PEER_BIN", {"--robot", std::to_string(r), "--config", peer_cfg},
                           "peer" + std::to_string(r) + ".log"));
  }
  test::ChildProcess& feeder =
      spawn("CDC_FEEDER_BIN", {"--keyframes", std::to_string(kKeyframes), "--rate-hz", "20", "--wait-readers", "4"},
            "feeder.log");
  ASSERT_TRUE(central_alive.wait_for(dds::Liveliness::kAlive, 15s)) << "the central never came up";

  // Latest mode message per robot.
  std::map<uint32_t, cdc_msg_ModeState> latest;
  const auto poll_modes = [&] {
    modes.take(256).for_each_valid([&](const cdc_msg_ModeState& m, const dds_sample_info_t&) {
      auto it = latest.find(m.robot_id);
      if (it == latest.end() || m.transition_count >= it->second.transition_count) latest[m.robot_id] = m;
    });
  };
  const bool joined = dds::wait_until(
      [&] {
        poll_modes();
        return latest.size() == kRobots && std::all_of(latest.begin(), latest.end(), [](const auto& kv) {
                 return kv.second.mode == cdc_msg_MODE_CENTRALIZED;
               });
      },
      20000ms);
  ASSERT_TRUE(joined) << "the robots never joined the central";
  std::map<uint32_t, uint32_t> joined_transitions;
  for (const auto& [r, m] : latest) joined_transitions[r] = m.transition_count;

  flood(*participant_);
  const auto fed = feeder.wait(40s);
  ASSERT_TRUE(fed && WIFEXITED(*fed) && WEXITSTATUS(*fed) == 0) << "feeder failed";
  std::this_thread::sleep_for(3s);  // the central drains its readers
  poll_modes();
  for (const auto& [r, m] : latest) {
    EXPECT_EQ(m.mode, cdc_msg_MODE_CENTRALIZED) << "robot " << r;
    EXPECT_EQ(m.transition_count, joined_transitions[r]) << "robot " << r << " switched during the flood";
  }
  while (const auto e = central_alive.next_event(0ms)) {
    EXPECT_NE(e->state, dds::Liveliness::kLost) << "the central's liveliness lapsed";
  }
  EXPECT_EQ(central_alive.state(), dds::Liveliness::kAlive);
  for (uint32_t r = 0; r < kRobots; ++r) {  // the peers first: they switch when the central goes
    ASSERT_TRUE(end(*peers[r])) << "peer " << r << " did not stop cleanly";
    EXPECT_EQ(count_lines_with(read("peer" + std::to_string(r) + ".log"), "mode "), joined_transitions[r])
        << "robot " << r << " logged a switch after joining";
  }
  ASSERT_TRUE(end(central)) << "central did not stop cleanly";

  const auto stats = nlohmann::json::parse(read("central.json"));
  std::printf("central: %s\n", stats.dump().c_str());
  const auto count = [&](const char* key) { return stats.at(key).get<uint64_t>(); };
  const uint64_t pending = count("keyframes_pending");
  const auto& kf_losses = stats.at("reader_losses").at("keyframes");
  const uint64_t lost = kf_losses.at("lost").get<uint64_t>() + kf_losses.at("rejected").get<uint64_t>();
  EXPECT_LE(pending, count("max_pending_keyframes"));
  EXPECT_EQ(count("keyframes_accepted"), kRobots * kKeyframes + pending) << "only the flood waits";
  EXPECT_EQ(pending + count("keyframes_pending_full") + lost, kFlood) << "a hostile sample went uncounted";
  EXPECT_EQ(count("keyframes_rejected"), count("keyframes_pending_full"));
  EXPECT_EQ(stats.at("rejected").value(dds::topics::kKeyframe, uint64_t{0}), count("keyframes_rejected"));
  EXPECT_EQ(count("graph_poses"), kRobots * kKeyframes);
  for (const auto& s : stats.at("sessions")) {
    EXPECT_EQ(s.at("highest_contiguous_keyframe").get<int64_t>(), int64_t{kKeyframes} - 1);
  }
  const size_t refusal_lines = count_lines_with(read("central.log"), std::string("rejected ") + dds::topics::kKeyframe);
  std::printf("central: %zu log lines for %lu refused keyframes; update median %.2f ms, p90 %.2f ms\n", refusal_lines,
              static_cast<unsigned long>(count("keyframes_rejected")), stats.at("update_ms").at("median").get<double>(),
              stats.at("update_ms").at("p90").get<double>());
  EXPECT_GE(refusal_lines, 1u);
  EXPECT_LT(refusal_lines, 200u) << "refusals are logged without a rate limit";
}

TEST_F(CentralUnderAttack, ACentralSaysItKnowsNoWorldUntilItsHostRobotIsInIt) {
  dds::Topic<cdc_msg_RobotStatus> t_status(*participant_, dds::topics::kRobotStatus);
  dds::Reader<cdc_msg_RobotStatus> statuses(*participant_, t_status, dds::qos::keyed_state(16));
  start_central(write("central.yaml", "robots: 3\ncentral_on_robot: 0\nstatus_period_ms: 100\n"));
  std::vector<cdc_msg_RobotStatus> seen;
  const auto poll = [&] {
    statuses.take(64).for_each_valid([&](const cdc_msg_RobotStatus& m, const dds_sample_info_t&) {
      if (m.is_central) seen.push_back(m);
    });
  };
  ASSERT_TRUE(dds::wait_until(
      [&] {
        poll();
        return seen.size() >= 5;
      },
      15000ms))
      << "no status from the central";
  for (const auto& s : seen) {
    EXPECT_FALSE(s.world_valid) << "a central without robot 0's poses claims a world (at "
                                << dds::to_eigen(s.T_world_base.position).transpose() << ")";
  }
  // Robot 0's keyframes (about 2 m apart) place the central on robot 0's newest one.
  spawn("CDC_FEEDER_BIN", {"--robots", "1", "--keyframes", "30", "--rate-hz", "50", "--wait-readers", "1"},
        "feeder.log");
  const bool placed = dds::wait_until(
      [&] {
        poll();
        return !seen.empty() && seen.back().world_valid && dds::to_eigen(seen.back().T_world_base.position).norm() > 10;
      },
      15000ms);
  EXPECT_TRUE(placed) << "the central never placed itself on robot 0";
}

}  // namespace
}  // namespace cdc
