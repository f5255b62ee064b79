// cdc-pgo on the published pose-graph benchmarks: SE-Sync's objective reaches the published
// optimum f* (../shared/data/pose-graphs/optimal-costs.csv).
#include "run_command.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace {

namespace fs = std::filesystem;

struct Published {
  std::string dataset, file, fstar_text;
  double fstar = 0;
};

std::string data_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr ? env : "../shared/data";
}

std::vector<Published> published_optima() {
  std::vector<Published> out;
  std::ifstream in(data_dir() + "/pose-graphs/optimal-costs.csv");
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || line.rfind("dataset,", 0) == 0) {
      continue;
    }
    std::stringstream s(line);
    std::vector<std::string> cols;
    std::string c;
    while (std::getline(s, c, ',')) {
      cols.push_back(c);
    }
    if (cols.size() == 6 && cols[2] != "-") {
      out.push_back({cols[0], cols[2], cols[5], std::stod(cols[5])});
    }
  }
  return out;
}

// Half a unit in the last published digit of "6.432e3" or "5.23482e1".
double half_unit(const std::string& text) {
  const auto e = text.find_first_of("eE");
  const std::string mantissa = text.substr(0, e);
  const int exponent = e == std::string::npos ? 0 : std::stoi(text.substr(e + 1));
  const auto dot = mantissa.find('.');
  const int decimals = dot == std::string::npos ? 0 : static_cast<int>(mantissa.size() - dot - 1);
  return 0.5 * std::pow(10.0, exponent - decimals);
}

nlohmann::json run_pgo(const std::string& args) {
  const std::string cmd = std::string(std::getenv("CDC_PGO_BIN")) + " " + args;
  const auto r = cdc::test::run_command(cmd, /*merge_stderr=*/false);
  EXPECT_EQ(r.exit_code, 0) << cmd << "\n" << r.output;
  return nlohmann::json::parse(r.output);
}

TEST(PgoTool, ReachesThePublishedOptimaWithSeSyncWeights) {
  const auto optima = published_optima();
  if (optima.empty()) {
    GTEST_SKIP() << "reference data absent: CDC_DATA_DIR/pose-graphs/optimal-costs.csv not found";
  }
  ASSERT_NE(std::getenv("CDC_PGO_BIN"), nullptr);
  for (const Published& p : optima) {
    const std::string path = data_dir() + "/pose-graphs/" + p.file;
    ASSERT_TRUE(fs::exists(path)) << path;
    const auto j = run_pgo(path + " --sesync-weights --json");
    const double f = j["sesync_objective"].get<double>();
    // The published figure stands for [f* - h, f* + h]; f must be within 1e-4 of that interval.
    const double h = half_unit(p.fstar_text);
    const double lo = (p.fstar - h) * (1.0 - 1e-4);
    const double hi = (p.fstar + h) * (1.0 + 1e-4);
    std::printf("%-15s f = %.7g, published f* = %s, relative difference %.2e, %d iterations, %.3f s\n",
                p.dataset.c_str(), f, p.fstar_text.c_str(), std::abs(f - p.fstar) / p.fstar, j["iterations"].get<int>(),
                j["time_s"].get<double>());
    EXPECT_GE(f, lo) << p.dataset;
    EXPECT_LE(f, hi) << p.dataset;
  }
}

TEST(PgoTool, WritesAGraphThatReadsBackAtTheSameCost) {
  const std::string path = data_dir() + "/pose-graphs/3d/smallGrid3D.g2o";
  if (!fs::exists(path)) {
    GTEST_SKIP() << "reference data absent: " << path;
  }
  const std::string out = (fs::temp_directory_path() / ("cdc_pgo_out_" + std::to_string(::getpid()) + ".g2o")).string();
  const auto first = run_pgo(path + " --json --out " + out);
  const auto again = run_pgo(out + " --init file --json");
  fs::remove(out);
  EXPECT_NEAR(again["initial_cost"].get<double>(), first["cost"].get<double>(), 1e-6 * first["cost"].get<double>());
  EXPECT_LE(again["iterations"].get<int>(), 1);
}

// The distributed solve converges in shape: every pose within 5 cm of the centralized estimate
// within 30 rounds, on the reference DGS graphs (2, 4 and 9 robots), with robots updating one after
// the other and all at once.
TEST(PgoTool, DistributedMatchesTheCentralizedEstimateWithinThirtyRounds) {
  const std::string base = data_dir() + "/multi-robot/dgs";
  if (!fs::exists(base)) {
    GTEST_SKIP() << "reference data absent: " << base;
  }
  for (const std::string mode : {"", " --parallel"}) {
    for (int robots : {2, 4, 9}) {
      const std::string folder = base + "/example_" + std::to_string(robots) + "robots";
      const auto j = run_pgo(folder + " --distributed --json" + mode);
      std::printf(
          "%s%d robots: %d rounds (%d rotation, %d translation), largest deviation from centralized %.4f m, RMS "
          "%.4f m, gap %.2e\n",
          mode.c_str(), robots, j["rounds"].get<int>(), j["rotation_rounds"].get<int>(),
          j["translation_rounds"].get<int>(), j["max_deviation_m"].get<double>(),
          j["ate_to_centralized_m"].get<double>(), j["gap_to_centralized"].get<double>());
      EXPECT_TRUE(j["converged"].get<bool>()) << "the centralized solve";
      EXPECT_TRUE(j["distributed_converged"].get<bool>()) << robots << " robots";
      EXPECT_LE(j["rounds"].get<int>(), 30);
      EXPECT_LT(j["max_deviation_m"].get<double>(), 0.05) << robots << " robots";
      EXPECT_LE(j["ate_to_centralized_m"].get<double>(), j["max_deviation_m"].get<double>());
      EXPECT_LT(j["gap_to_centralized"].get<double>(), 1e-3);
      EXPECT_EQ(j["bytes_per_robot"].size(), static_cast<size_t>(robots));
      EXPECT_EQ(j["bytes_per_round"].size(), j["rounds"].get<size_t>());
    }
  }
}

// The block Gauss-Seidel scheme stays available for comparison: it reaches 1 % of the centralized
// cost, not its shape.
TEST(PgoTool, BlockGaussSeidelReachesOnePercentOfCentralizedCost) {
  const std::string folder = data_dir() + "/multi-robot/dgs/example_9robots";
  if (!fs::exists(folder)) {
    GTEST_SKIP() << "reference data absent: " << folder;
  }
  const auto j = run_pgo(folder + " --distributed --distributed-method block-gs --json");
  std::printf("block-gs, 9 robots: 1%% of centralized after %d rounds, largest deviation %.3f m\n",
              j["rounds_to_1pct"].get<int>(), j["max_deviation_m"].get<double>());
  EXPECT_GE(j["rounds_to_1pct"].get<int>(), 0);
  EXPECT_LE(j["rounds_to_1pct"].get<int>(), 30);
  EXPECT_LT(j["gap_to_centralized"].get<double>(), 0.01);
}

// --init file on a graph without VERTEX lines runs odometry chaining and says so in its output.
TEST(PgoTool, InitFromAFileWithoutVerticesSaysItChainsOdometry) {
  const std::string path = data_dir() + "/pose-graphs/2d/manhattan.g2o";
  if (!fs::exists(path)) {
    GTEST_SKIP() << "reference data absent: " << path;
  }
  const auto j = run_pgo(path + " --init file --max-iterations 1 --json");
  EXPECT_EQ(j["init_requested"], "file");
  EXPECT_EQ(j["init"], "odometry");
  EXPECT_THAT(j["init_note"].get<std::string>(), ::testing::HasSubstr("no vertices"));
}

// A graph whose information is not positive definite but gives positive SE-Sync weights (as cubicle's):
// refused for the full-information cost, solved with --sesync-weights, where that cost is reported as none.
TEST(PgoTool, SeSyncWeightsAcceptIndefiniteInformationAndReportNoFullCost) {
  const std::string file =
      (fs::temp_directory_path() / ("cdc_pgo_indef_" + std::to_string(::getpid()) + ".g2o")).string();
  const std::string q = " 0 0 0 1", definite = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  const std::string indefinite = " 1 0 0 5 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";  // eigenvalue 1 - 5 < 0
  std::ofstream(file) << "EDGE_SE3:QUAT 0 1 1 0 0" << q << definite << "EDGE_SE3:QUAT 1 2 1 0 0" << q << definite
                      << "EDGE_SE3:QUAT 0 2 2.1 0 0" << q << indefinite;
  const auto refused = cdc::test::run_command(std::string(std::getenv("CDC_PGO_BIN")) + " " + file + " --json");
  EXPECT_NE(refused.exit_code, 0);
  EXPECT_THAT(refused.output, ::testing::HasSubstr("not positive definite"));
  const auto j = run_pgo(file + " --sesync-weights --init odometry --json");
  fs::remove(file);
  EXPECT_EQ(j["indefinite_information"], 1);
  EXPECT_TRUE(j["cost"].is_null());
  EXPECT_TRUE(j["initial_cost"].is_null());
  EXPECT_GT(j["sesync_objective"].get<double>(), 0.0);
  EXPECT_LT(j["sesync_objective"].get<double>(), j["initial_sesync_objective"].get<double>());
}

}  // namespace
