// cdc-loops as a user runs it: `pcm` on the external multi-robot graphs (JSON), `run` on a
// short simulated dataset (precision against its ground truth, output files), and clear errors
// on bad input.
#include "run_command.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace {

namespace fs = std::filesystem;

struct Result {
  int code = -1;
  std::string out;
};

Result run(const std::string& cmd) {
  const auto r = cdc::test::run_command(cmd);
  return {r.exit_code, r.output};
}

std::string data_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr ? env : "../shared/data";
}

std::string loops_bin() { return std::getenv("CDC_LOOPS_BIN"); }

TEST(LoopsTool, PcmKeepsTheReferenceCountsOnTheSpoiledGraphs) {
  const std::string dir = data_dir() + "/multi-robot/pcm";
  if (!fs::exists(dir)) GTEST_SKIP() << "reference data absent: " << dir << " not found";
  for (const auto& [set, kept, total] : {std::tuple{"spoiled_2robots", 10, 20}, std::tuple{"spoiled_4robots", 24, 48},
                                         std::tuple{"clean_2robots", 10, 10}}) {
    const Result r = run(loops_bin() + " pcm " + dir + "/" + set + " --json");
    ASSERT_EQ(r.code, 0) << r.out;
    const auto j = nlohmann::json::parse(r.out.substr(r.out.rfind('{')));
    EXPECT_EQ(j["accepted"].size(), static_cast<size_t>(kept)) << set;
    EXPECT_EQ(j["accepted"].size() + j["rejected"].size(), static_cast<size_t>(total)) << set;
  }
}

TEST(LoopsTool, RunJudgesASimulatedDatasetAgainstItsGroundTruth) {
  const fs::path tmp = fs::temp_directory_path() / ("cdc_loops_tool_" + std::to_string(::getpid()));
  // Two robots on figure-eights that cross at the start, 45 s.
  fs::create_directories(tmp);
  const std::string scenario = (tmp / "crossing.yaml").string();
  std::ofstream(scenario)
      << "name: crossing_2robots\nseed: 5\ntrajectories:\n  source: procedural\n  pattern: crossing\n"
         "  robots: 2\n  speed_mps: 4\n  size_m: 60\n  duration_s: 45\nlidar: vlp16\n";
  Result g = run(std::string(std::getenv("CDC_SIM_BIN")) + " generate --scenario " + scenario + " --out " +
                 (tmp / "ds").string() + " --data " + data_dir());
  ASSERT_EQ(g.code, 0) << g.out;
  const Result r = run(loops_bin() + " run " + (tmp / "ds").string() + " --out " + (tmp / "out").string() + " --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out.substr(r.out.rfind('{')));
  EXPECT_GT(j["keyframes"].get<int>(), 100);  // every 2 m of 2 x 180 m
  EXPECT_GT(j["revisits"].get<int>(), 20);
  EXPECT_GT(j["accepted"].get<int>(), 20);
  EXPECT_EQ(j["precision"].get<double>(), 1.0);
  EXPECT_GT(j["recall"].get<double>(), 0.5);
  for (const char* f : {"keyframes.csv", "loops.csv", "report.json"}) {
    EXPECT_TRUE(fs::exists(tmp / "out" / f)) << f;
  }
  std::ifstream csv(tmp / "out" / "loops.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_EQ(header, "robot_a,keyframe_a,robot_b,keyframe_b,tx,ty,tz,qx,qy,qz,qw,fitness,correct,error_m,error_deg");
  fs::remove_all(tmp);
}

TEST(LoopsTool, NamesWhatIsWrongWithItsInput) {
  const fs::path tmp = fs::temp_directory_path() / ("cdc_loops_bad_" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  Result r = run(loops_bin() + " run " + tmp.string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("robot_0: missing"), std::string::npos) << r.out;
  r = run(loops_bin() + " run " + (tmp / "nope").string());
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("nope"), std::string::npos) << r.out;
  // The service's configuration: a bad value and an unknown key are named; a good file is taken (and
  // the run then stops at the dataset).
  std::ofstream(tmp / "bad.yaml") << "verification:\n  max_iterations: 0\n  neighbors: 20\n";
  r = run(loops_bin() + " run " + tmp.string() + " --config " + (tmp / "bad.yaml").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("verification.max_iterations"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("verification.neighbors"), std::string::npos) << r.out;
  std::ofstream(tmp / "good.yaml") << "verification:\n  max_iterations: 20\n";
  r = run(loops_bin() + " run " + tmp.string() + " --config " + (tmp / "good.yaml").string());
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("robot_0: missing"), std::string::npos) << r.out;
  r = run(loops_bin() + " --help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("run DATASET"), std::string::npos);
  fs::remove_all(tmp);
}

}  // namespace
