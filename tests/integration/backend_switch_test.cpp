// The back-ends over DDS with real processes: a central optimiser, three peer optimisers and a
// feeder standing in for the robots' front-ends and loop closure (loopback configuration).
//  * SIGKILL the central: every robot reports DISTRIBUTED within lease + 200 ms and keeps
//    correcting; a restarted central brings every robot back after the dwell and ends up holding
//    every keyframe and loop closure exactly once, at the optimum of the complete graph.
//  * A robot driven out of the central's range switches at CR_0 and comes back after the dwell;
//    no correction any robot publishes jumps by more than the fusion thresholds.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"
#include "child_process.hpp"
#include "process_test.hpp"
#include "swarm_stream.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <sys/wait.h>
#include <unistd.h>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <thread>

namespace cdc {
namespace {

using namespace std::chrono_literals;
using Clock = std::chrono::steady_clock;

struct ModeSample {
  Clock::time_point received;
  cdc_msg_ModeState msg;
};

struct CorrectionSample {
  Clock::time_point received;
  uint32_t robot;
  cdc_msg_PoseSource source;
  Eigen::Isometry3d T_world_robot;
};

class BackendSwarm : public test::ProcessTest {
 protected:
  BackendSwarm() : ProcessTest("backend", {"CDC_CENTRAL_BIN", "CDC_PEER_BIN", "CDC_FEEDER_BIN"}) {}

  void set_up() override {
    t_mode_ = std::make_unique<dds::Topic<cdc_msg_ModeState>>(*participant_, dds::topics::kMode);
    t_corr_ = std::make_unique<dds::Topic<cdc_msg_OptimizedPoses>>(*participant_, dds::topics::kCorrection);
    t_kf_ = std::make_unique<dds::Topic<cdc_msg_Keyframe>>(*participant_, dds::topics::kKeyframe);
    t_loop_ = std::make_unique<dds::Topic<cdc_msg_LoopClosure>>(*participant_, dds::topics::kLoopClosure);
    dds::Qos deep;
    deep.reliable().keep_last(4096).transient_local();
    r_mode_ = std::make_unique<dds::Reader<cdc_msg_ModeState>>(*participant_, *t_mode_, deep);
    // Corrections are written in each robot's partition (for its own front-end).
    r_corr_ = std::make_unique<dds::Reader<cdc_msg_OptimizedPoses>>(
        *participant_, *t_corr_, dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader()));
  }

  void stop_processes() override {
    for (auto* p : {&central_, &feeder_}) {
      stop(*p);
    }
    for (auto& p : peers_) {
      stop(p);
    }
  }

  static void stop(test::ChildProcess& p) { p.stop(5s); }

  void start_central(const std::string& config, const std::string& tag) {
    central_ =
        test::ChildProcess::spawn({std::getenv("CDC_CENTRAL_BIN"), "--config", config, "--stats-out",
                                   path("central_" + tag + ".json"), "--graph-out", path("central_" + tag + ".g2o")},
                                  path("central_" + tag + ".log"));
  }
  void start_peers(const std::string& config) {
    for (int r = 0; r < 3; ++r) {
      peers_.push_back(test::ChildProcess::spawn({std::getenv("CDC_PEER_BIN"), "--robot", std::to_string(r), "--config",
                                                  config, "--stats-out", path("peer" + std::to_string(r) + ".json")},
                                                 path("peer" + std::to_string(r) + ".log")));
    }
  }
  void start_feeder(std::vector<std::string> args) {
    args.insert(args.begin(), std::getenv("CDC_FEEDER_BIN"));
    feeder_ = test::ChildProcess::spawn(args, path("feeder.log"));
  }

  void poll() {
    r_mode_->take(256).for_each_valid([&](const cdc_msg_ModeState& m, const dds_sample_info_t&) {
      modes_.push_back({Clock::now(), m});
    });
    r_corr_->take(1024).for_each_valid([&](const cdc_msg_OptimizedPoses& m, const dds_sample_info_t&) {
      corrections_.push_back({Clock::now(), m.robot_id, m.source, dds::to_eigen(m.T_world_robot)});
    });
  }

  // Latest mode per robot, as far as the test has seen.
  std::map<uint32_t, cdc_msg_ModeState> latest() const {
    std::map<uint32_t, cdc_msg_ModeState> m;
    for (const auto& s : modes_) {
      auto it = m.find(s.msg.robot_id);
      if (it == m.end() || s.msg.transition_count >= it->second.transition_count) {
        m[s.msg.robot_id] = s.msg;
      }
    }
    return m;
  }

  bool wait_all(cdc_msg_BackendMode mode, std::chrono::milliseconds timeout) {
    const auto deadline = Clock::now() + timeout;
    while (Clock::now() < deadline) {
      poll();
      const auto l = latest();
      if (l.size() == 3 && std::all_of(l.begin(), l.end(), [&](const auto& kv) { return kv.second.mode == mode; })) {
        return true;
      }
      std::this_thread::sleep_for(10ms);
    }
    return false;
  }

  // First transition of `robot` to `mode` received after `since`.
  std::optional<ModeSample> first_transition(uint32_t robot, cdc_msg_BackendMode mode, Clock::time_point since) const {
    uint32_t seen_count = 0;
    for (const auto& s : modes_) {
      if (s.msg.robot_id == robot && s.msg.mode == mode && s.received >= since && s.msg.transition_count > seen_count) {
        return s;
      }
    }
    return std::nullopt;
  }

  nlohmann::json read_json(const std::string& name) const {
    std::ifstream in(path(name));
    return nlohmann::json::parse(in);
  }

  std::unique_ptr<dds::Topic<cdc_msg_ModeState>> t_mode_;
  std::unique_ptr<dds::Topic<cdc_msg_OptimizedPoses>> t_corr_;
  std::unique_ptr<dds::Topic<cdc_msg_Keyframe>> t_kf_;
  std::unique_ptr<dds::Topic<cdc_msg_LoopClosure>> t_loop_;
  std::unique_ptr<dds::Reader<cdc_msg_ModeState>> r_mode_;
  std::unique_ptr<dds::Reader<cdc_msg_OptimizedPoses>> r_corr_;
  test::ChildProcess central_, feeder_;
  std::vector<test::ChildProcess> peers_;
  std::vector<ModeSample> modes_;
  std::vector<CorrectionSample> corrections_;
};

TEST_F(BackendSwarm, CentralOutageSwitchesEveryRobotAndLosesNothing) {
  constexpr auto kLease = 1000ms;
  const std::string central_cfg = write("central.yaml", "robots: 3\nlease_ms: 1000\n");
  const std::string peer_cfg = write("peer.yaml", "robots: 3\nrange_m: 1.0e6\ndwell_ms: 2000\nmask_ms: 1000\n");
  start_central(central_cfg, "first");
  start_peers(peer_cfg);
  test::SwarmStreamOptions so;
  so.keyframes_per_robot = 400;
  start_feeder({"--keyframes", "400", "--rate-hz", "25", "--wait-readers", "4"});

  ASSERT_TRUE(wait_all(cdc_msg_MODE_CENTRALIZED, 20s)) << "robots never joined the central";
  std::this_thread::sleep_for(3s);
  const auto kill_time = Clock::now();
  central_.signal(SIGKILL);
  ASSERT_TRUE(central_.wait(5s));
  ASSERT_TRUE(wait_all(cdc_msg_MODE_DISTRIBUTED, 5s)) << "robots never noticed the central was gone";
  for (uint32_t r = 0; r < 3; ++r) {
    const auto t = first_transition(r, cdc_msg_MODE_DISTRIBUTED, kill_time);
    ASSERT_TRUE(t) << "robot " << r;
    EXPECT_EQ(t->msg.reason, cdc_msg_REASON_LIVELINESS_LOST) << "robot " << r;
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(t->received - kill_time);
    std::printf("robot %u: DISTRIBUTED %lld ms after the central was killed\n", r, static_cast<long long>(ms.count()));
    EXPECT_LE(ms, kLease + 200ms) << "robot " << r;
  }
  // Malformed input during the outage: the robots must reject it and carry on.
  {
    dds::Writer<cdc_msg_Keyframe> w(*participant_, *t_kf_, dds::qos::event_stream(16));
    dds::Writer<cdc_msg_LoopClosure> wl(*participant_, *t_loop_, dds::qos::event_stream(16));
    ASSERT_TRUE(w.wait_for_readers(3, 5s));
    cdc_msg_Keyframe bad{};
    bad.robot_id = 1;
    bad.keyframe_id = 100000;
    bad.T_odom_keyframe.orientation.w = std::numeric_limits<double>::quiet_NaN();
    bad.T_prev_keyframe.orientation.w = 1;
    w.write(bad);
    cdc_msg_LoopClosure unknown{};
    unknown.robot_a = 1;
    unknown.robot_b = 9;
    unknown.sender_robot_id = 1;
    unknown.T_a_b.orientation.w = 1;
    wl.write(unknown);
  }
  std::this_thread::sleep_for(3s);
  poll();
  for (uint32_t r = 0; r < 3; ++r) {
    const size_t n = static_cast<size_t>(std::count_if(corrections_.begin(), corrections_.end(), [&](const auto& c) {
      return c.robot == r && c.received > kill_time + 1500ms && c.source == cdc_msg_SOURCE_DISTRIBUTED;
    }));
    EXPECT_GT(n, 10u) << "robot " << r << " stopped correcting its front-end during the outage";
  }

  const auto restart_time = Clock::now();
  start_central(central_cfg, "second");
  ASSERT_TRUE(wait_all(cdc_msg_MODE_CENTRALIZED, 15s)) << "robots never rejoined the restarted central";
  for (uint32_t r = 0; r < 3; ++r) {
    const auto t = first_transition(r, cdc_msg_MODE_CENTRALIZED, restart_time);
    ASSERT_TRUE(t);
    EXPECT_EQ(t->msg.reason, cdc_msg_REASON_BACK_IN_RANGE);
    EXPECT_GE(t->received - restart_time, 2000ms) << "robot " << r << " returned before the dwell";
  }
  const auto fed = feeder_.wait(40s);
  ASSERT_TRUE(fed && WIFEXITED(*fed) && WEXITSTATUS(*fed) == 0) << "feeder failed";
  std::this_thread::sleep_for(4s);  // re-sends after the grace period
  central_.signal(SIGTERM);
  const auto st = central_.wait(30s);
  ASSERT_TRUE(st && WIFEXITED(*st) && WEXITSTATUS(*st) == 0) << "central did not stop cleanly";
  for (auto& p : peers_) {
    p.signal(SIGTERM);
    const auto ps = p.wait(10s);
    ASSERT_TRUE(ps && WIFEXITED(*ps) && WEXITSTATUS(*ps) == 0) << "a peer optimiser did not stop cleanly";
  }

  // Exactly once: every keyframe and every loop closure of the stream, each held once.
  const auto stream = test::make_swarm_stream(so);
  const auto stats = read_json("central_second.json");
  std::printf("restarted central: %s\n", stats.dump().c_str());
  EXPECT_EQ(stats["graph_poses"].get<size_t>(), 1200u);
  EXPECT_EQ(stats["keyframes_accepted"].get<size_t>(), 1200u);
  EXPECT_EQ(stats["loops_accepted"].get<size_t>(), stream.loops.size());
  EXPECT_EQ(stats["graph_factors"].get<size_t>(), 3u * 399u + stream.loops.size() + 1u);
  for (const auto& s : stats["sessions"]) {
    EXPECT_EQ(s["keyframes_held"].get<size_t>(), 400u);
    EXPECT_EQ(s["highest_contiguous_keyframe"].get<int64_t>(), 399);
  }
  for (uint32_t r = 0; r < 3; ++r) {
    EXPECT_GE(read_json("peer" + std::to_string(r) + ".json")["rejected_samples"].get<uint64_t>(), r == 1 ? 2u : 0u);
  }

  // The same optimum as the complete graph solved offline (what a run without outage reaches).
  graph::PoseGraph reference;
  for (const auto& robot : stream.keyframes) {
    for (const auto& kf : robot) {
      if (kf.id > 0) {
        reference.add_between(graph::make_key(kf.robot, kf.id - 1u), graph::make_key(kf.robot, kf.id),
                              kf.T_prev_keyframe, kf.information);
      }
    }
  }
  for (const auto& l : stream.loops) {
    reference.add_between(graph::make_key(l.robot_a, l.keyframe_a), graph::make_key(l.robot_b, l.keyframe_b), l.T_a_b,
                          l.information);
  }
  reference.add_prior(graph::make_key(0, 0), Eigen::Isometry3d::Identity(), graph::Matrix6d::Identity() * 1e8);
  // The central's defaults: loops through one keyframe share its information.
  graph::share_loop_information(reference);
  ASSERT_TRUE(graph::chordal_initialise(reference));
  graph::SolverOptions so_ref;
  so_ref.max_iterations = 500;
  so_ref.function_tolerance = 1e-14;
  so_ref.gradient_tolerance = 1e-14;
  so_ref.parameter_tolerance = 1e-14;
  // The central's default: GNC in full passes, from the least-squares solution. It holds no loop of
  // this stream out (no wrong loops, information that matches the noise), so its optimum is the
  // least-squares one.
  EXPECT_EQ(stats["loops_outliers"].get<uint64_t>(), 0u);
  graph::solve(reference, so_ref);
  reference.factors.erase(std::remove_if(reference.factors.begin(), reference.factors.end(),
                                         [](const auto& f) { return f.kind == graph::FactorKind::kPrior; }),
                          reference.factors.end());
  graph::PoseGraph central = graph::read_g2o(path("central_second.g2o"));  // information as measured
  graph::share_loop_information(central);
  const double f_ref = graph::full_information_cost(reference);
  const double f_central = graph::full_information_cost(central);
  std::printf("final cost: central %.9g, offline reference %.9g\n", f_central, f_ref);
  EXPECT_NEAR(f_central, f_ref, 1e-6 * f_ref);
}

TEST_F(BackendSwarm, RangeTriggerSwitchesAndCorrectionsNeverJump) {
  const double pos_max = 0.3, rot_max_deg = 1.0;
  const std::string central_cfg = write("central.yaml", "robots: 3\ncentral_on_robot: 0\n");
  const std::string peer_cfg = write("peer.yaml",
                                     "robots: 3\nrange_m: 120\nhysteresis_m: 10\ndwell_ms: 1500\nmask_ms: 1000\n"
                                     "fusion:\n  pos_max_m: 0.3\n  rot_max_deg: 1.0\n");
  start_central(central_cfg, "range");
  start_peers(peer_cfg);
  // 80 m x 60 m lap (at most 100 m between robots on it); robot 2 leaves it for 200 m and returns.
  start_feeder({"--keyframes", "450", "--rate-hz", "30", "--wait-readers", "4", "--block-w", "80", "--block-h", "60",
                "--excursion-robot", "2", "--excursion-m", "200"});
  const auto fed = feeder_.wait(60s);
  ASSERT_TRUE(fed && WIFEXITED(*fed) && WEXITSTATUS(*fed) == 0) << "feeder failed";
  std::this_thread::sleep_for(3s);
  poll();

  std::vector<cdc_msg_ModeState> robot2;
  for (const auto& s : modes_) {
    if (s.msg.robot_id == 2 && (robot2.empty() || s.msg.transition_count > robot2.back().transition_count)) {
      robot2.push_back(s.msg);
    }
    if (s.msg.robot_id != 2) {
      EXPECT_NE(s.msg.reason, cdc_msg_REASON_OUT_OF_RANGE) << "robot " << s.msg.robot_id << " never left the lap";
    }
  }
  bool left = false, returned = false;
  for (const auto& m : robot2) {
    std::printf("robot 2: transition %u -> %s (reason %d) at %.1f m from the central\n", m.transition_count,
                m.mode == cdc_msg_MODE_CENTRALIZED ? "CENTRALIZED" : "DISTRIBUTED", static_cast<int>(m.reason),
                m.distance_to_central);
    if (m.mode == cdc_msg_MODE_DISTRIBUTED && m.reason == cdc_msg_REASON_OUT_OF_RANGE) {
      left = true;
      EXPECT_GT(m.distance_to_central, 120.0);
      EXPECT_LT(m.distance_to_central, 140.0) << "the switch came late";
    }
    if (left && m.mode == cdc_msg_MODE_CENTRALIZED && m.reason == cdc_msg_REASON_BACK_IN_RANGE) {
      returned = true;
      EXPECT_LT(m.distance_to_central, 110.0);
    }
  }
  EXPECT_TRUE(left) << "robot 2 never switched on range";
  EXPECT_TRUE(returned) << "robot 2 never came back";

  std::map<uint32_t, Eigen::Isometry3d> last;
  size_t checked = 0;
  double worst_t = 0, worst_r = 0;
  for (const auto& c : corrections_) {
    auto it = last.find(c.robot);
    if (it != last.end()) {
      const double dt = (c.T_world_robot.translation() - it->second.translation()).norm();
      const double dr = geometry::rotation_angle(it->second.rotation().transpose() * c.T_world_robot.rotation());
      worst_t = std::max(worst_t, dt);
      worst_r = std::max(worst_r, dr);
      ++checked;
    }
    last[c.robot] = c.T_world_robot;
  }
  std::printf("%zu consecutive corrections checked: largest step %.3f m, %.3f deg\n", checked, worst_t,
              worst_r * 180 / M_PI);
  EXPECT_GT(checked, 300u);
  EXPECT_LE(worst_t, pos_max + 1e-6);
  EXPECT_LE(worst_r, rot_max_deg * M_PI / 180 + 1e-6);
}

}  // namespace
}  // namespace cdc
