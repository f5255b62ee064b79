// cdc-peer-replay end to end on a synthetic three-robot stream: it reads the graph, the keyframes'
// stamps and the ground truth, replays the damped rounds close to the centralized optimum, and
// refuses a graph that holds more robots than it was told; given each robot's own graph, it also
// scores the run's own estimate.
#include "cdc/geometry/trajectory.hpp"
#include "cdc/graph/g2o.hpp"
#include "run_command.hpp"
#include "swarm_stream.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <string>

namespace {

namespace fs = std::filesystem;

cdc::test::CommandResult run_replay(const std::string& args) {
  return cdc::test::run_command(std::string(std::getenv("CDC_PEER_REPLAY_BIN")) + " " + args);
}

class PeerReplayTool : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("cdc_peer_replay_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    cdc::test::SwarmStreamOptions o;
    o.robots = 3;
    o.keyframes_per_robot = 100;
    stream_ = cdc::test::make_swarm_stream(o);
    const auto& s = stream_;
    cdc::test::write_stream_g2o(s, (dir_ / "graph.g2o").string());
    for (uint32_t r = 0; r < 3; ++r) {
      cdc::geometry::Trajectory kf, truth;
      for (const auto& k : s.keyframes[r]) {
        const int64_t stamp = static_cast<int64_t>(k.id) * 500'000'000;  // a keyframe every 0.5 s
        kf.push_back({stamp, k.T_odom_keyframe});
        truth.push_back({stamp, k.T_world_truth});
      }
      const fs::path rd = dir_ / "run" / ("robot_" + std::to_string(r)),
                     td = dir_ / "truth" / ("robot_" + std::to_string(r));
      fs::create_directories(rd);
      fs::create_directories(td);
      cdc::geometry::write_tum((rd / "keyframes.tum").string(), kf);
      cdc::geometry::write_tum((td / "groundtruth.tum").string(), truth);
    }
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string args(const std::string& extra) const {
    return (dir_ / "graph.g2o").string() + " --run " + (dir_ / "run").string() + " --truth " +
           (dir_ / "truth").string() + " " + extra;
  }
  fs::path dir_;
  cdc::test::SwarmStream stream_;
};

TEST_F(PeerReplayTool, ReplaysTheDampedRoundsCloseToTheCentralizedOptimum) {
  // Loops arrive one by one here and the rounds are first order: 60 s after the last keyframe the
  // joint cost is about 4 % above the optimum (the KITTI graphs' replays end at it). A replay that
  // lost loops, separators or keyframes on the way would end far from it.
  const cdc::test::CommandResult r = run_replay(args("--round-ms 100 --tail 60"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::smatch m;
  ASSERT_TRUE(
      std::regex_search(r.output, m, std::regex(R"(joint cost: distributed ([0-9.]+), centralized optimum ([0-9.]+))")))
      << r.output;
  const double distributed = std::stod(m[1]), optimum = std::stod(m[2]);
  EXPECT_GT(optimum, 0.0);
  EXPECT_LT(distributed, optimum * 1.1) << r.output;
  EXPECT_GE(distributed, optimum * (1 - 1e-4)) << r.output;
  for (int robot = 0; robot < 3; ++robot) {
    EXPECT_NE(r.output.find("robot " + std::to_string(robot) + ": 100 keyframes"), std::string::npos) << r.output;
  }
}

TEST_F(PeerReplayTool, AppliesTheRunsRadioTimeline) {
  // Every robot pair cut from the start: no inter-robot loop arrives, nothing crosses, and the robots
  // stay in their own frames, far from the joint optimum.
  std::ofstream(dir_ / "links.csv") << "wall_s,sim_s,a,b,state\n0.1,0.0,0,1,down\n0.1,0.0,0,2,down\n0.1,0.0,1,2,down\n";
  const cdc::test::CommandResult cut = run_replay(args("--links " + (dir_ / "links.csv").string()));
  ASSERT_EQ(cut.exit_code, 0) << cut.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(cut.output, m,
                                std::regex(R"(joint cost: distributed ([0-9.]+), centralized optimum ([0-9.]+))")))
      << cut.output;
  EXPECT_GT(std::stod(m[1]), 10 * std::stod(m[2])) << cut.output;
  for (int robot = 0; robot < 3; ++robot) {
    EXPECT_TRUE(std::regex_search(cut.output, std::regex("robot " + std::to_string(robot) +
                                                         R"(: 100 keyframes, \d+ rounds, 0 separator poses sent)")))
        << cut.output;
  }

  std::ofstream(dir_ / "bad.csv") << "wall_s,sim_s,a,b,state\n0.1,0.0,0,1,sideways\n";
  const cdc::test::CommandResult bad = run_replay(args("--links " + (dir_ / "bad.csv").string()));
  EXPECT_EQ(bad.exit_code, 2) << bad.output;
  EXPECT_NE(bad.output.find("bad.csv:2"), std::string::npos) << bad.output;
}

TEST_F(PeerReplayTool, ScoresTheRunsOwnEstimateFromEachRobotsGraph) {
  // Each robot's graph as a peer writes it: its own keyframes (here at the truth), its odometry, the
  // loops it takes part in and the peers' separators those loops touch. The run's own estimate is
  // then the truth: zero ATE, and a joint cost no lower than the optimum's.
  namespace graph = cdc::graph;
  const graph::PoseGraph whole = graph::read_g2o((dir_ / "graph.g2o").string());
  std::string files;
  for (uint32_t r = 0; r < 3; ++r) {
    graph::PoseGraph part;
    for (const auto& k : stream_.keyframes[r]) part.poses[graph::make_key(r, k.id)] = k.T_world_truth;
    for (const graph::Factor& f : whole.factors) {
      if (graph::robot_of(f.a) != r && graph::robot_of(f.b) != r) continue;
      part.factors.push_back(f);
      for (const graph::Key k : {f.a, f.b}) part.poses.emplace(k, whole.poses.at(k));
    }
    const fs::path path = dir_ / ("peer_graph_" + std::to_string(r) + ".g2o");
    graph::write_g2o(path.string(), part);
    files += path.string() + " ";
  }
  const cdc::test::CommandResult r =
      cdc::test::run_command(std::string(std::getenv("CDC_PEER_REPLAY_BIN")) + " " + files + "--run " +
                             (dir_ / "run").string() + " --truth " + (dir_ / "truth").string() + " --tail 5");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, std::regex(R"(centralized optimum ([0-9.]+))"))) << r.output;
  const double optimum = std::stod(m[1]);
  ASSERT_TRUE(std::regex_search(r.output, m, std::regex(R"(joint cost of the run's own estimate[^:]*: ([0-9.]+))")))
      << r.output;
  EXPECT_GE(std::stod(m[1]), optimum * (1 - 1e-4)) << r.output;
  for (int robot = 0; robot < 3; ++robot) {
    ASSERT_TRUE(std::regex_search(
        r.output, m, std::regex("robot " + std::to_string(robot) + R"(: ATE of the run's own estimate ([0-9.e-]+) m)")))
        << r.output;
    EXPECT_LT(std::stod(m[1]), 1e-3) << r.output;
  }
  // One graph holds no robot's own view: no such line.
  const cdc::test::CommandResult one = run_replay(args("--tail 5"));
  ASSERT_EQ(one.exit_code, 0) << one.output;
  EXPECT_EQ(one.output.find("own estimate"), std::string::npos) << one.output;
}

TEST_F(PeerReplayTool, RefusesAGraphWithMoreRobotsThanGiven) {
  const cdc::test::CommandResult r = run_replay(args("--robots 2"));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("holds robot 2"), std::string::npos) << r.output;
}

}  // namespace
