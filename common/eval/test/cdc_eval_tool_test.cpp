// cdc-eval on the real KITTI ground truth (sequence 05) against perturbed copies with known errors.
#include "cdc/geometry/se3.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "run_command.hpp"
#include "temp_dir.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

namespace cdc {
namespace {

namespace fs = std::filesystem;
using geometry::Trajectory;

using ToolRun = test::CommandResult;

ToolRun run(const std::string& args) {
  return test::run_command(std::string(std::getenv("CDC_EVAL_BIN")) + " " + args);
}

class CdcEvalTool : public test::TempDirTest {
 protected:
  CdcEvalTool() : TempDirTest("eval_tool", "CDC_EVAL_BIN") {}

  // KITTI sequence 05 ground truth, or empty (and the test skips) when the data folder is absent.
  std::string kitti_gt() {
    const char* env = std::getenv("CDC_DATA_DIR");
    const fs::path path = fs::path(env != nullptr ? env : "../shared/data") / "kitti/poses/05.txt";
    return fs::exists(path) ? path.string() : std::string();
  }
  nlohmann::json read_json(const std::string& name) const {
    std::ifstream in(path(name));
    return nlohmann::json::parse(in);
  }
};

#define CDC_REQUIRE_KITTI(var)                                                          \
  const std::string var = kitti_gt();                                                   \
  if (var.empty()) {                                                                    \
    GTEST_SKIP() << "reference data absent: CDC_DATA_DIR/kitti/poses/05.txt not found " \
                    "(set CDC_DATA_DIR to the shared data folder)";                     \
  }

TEST_F(CdcEvalTool, RigidlyMovedCopyHasZeroErrorAfterAlignment) {
  CDC_REQUIRE_KITTI(gt_path);
  const Trajectory gt = geometry::read_kitti(gt_path);
  ASSERT_EQ(gt.size(), 2761u);
  Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
  M.linear() = geometry::from_rpy(0.05, -0.1, 1.2);
  M.translation() = Eigen::Vector3d(300, -20, 7);
  Trajectory est = gt;
  for (auto& p : est) {
    p.pose = M * p.pose;
  }
  geometry::write_kitti(path("moved.txt"), est);
  const ToolRun r = run("--gt " + gt_path + " --est " + path("moved.txt") + " --json " + path("out.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = read_json("out.json")["trajectories"][0];
  EXPECT_EQ(j["poses"]["matched"], 2761);
  EXPECT_NEAR(j["gt_length_m"].get<double>(), 2205.6, 1.0);  // KITTI 05 is about 2.2 km
  EXPECT_LT(j["ate_m"]["rmse"].get<double>(), 1e-5);
  EXPECT_LT(j["rpe_frames"]["trans_m"]["rmse"].get<double>(), 1e-5);
  EXPECT_LT(j["kitti_drift"]["trans_pct"].get<double>(), 1e-5);
  // Without alignment the rigid offset is the whole error.
  const ToolRun none =
      run("--gt " + gt_path + " --est " + path("moved.txt") + " --align none --json " + path("n.json"));
  ASSERT_EQ(none.exit_code, 0) << none.output;
  EXPECT_GT(read_json("n.json")["trajectories"][0]["ate_m"]["rmse"].get<double>(), 100.0);
}

TEST_F(CdcEvalTool, AlternatingOffsetGivesItsSizeAsAteAndTwiceAsRpe) {
  CDC_REQUIRE_KITTI(gt_path);
  const double d = 0.05;  // [m], world z, alternating sign
  Trajectory est = geometry::read_kitti(gt_path);
  for (size_t i = 0; i < est.size(); ++i) {
    est[i].pose.translation().z() += (i % 2 == 0 ? d : -d);
  }
  geometry::write_tum(path("alt.tum"), est);  // TUM estimate against KITTI ground truth
  const ToolRun r = run("--gt " + gt_path + " --est " + path("alt.tum") + " --align none --json " + path("out.json") +
                        " --svg " + path("plot.svg"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = read_json("out.json")["trajectories"][0];
  EXPECT_NEAR(j["ate_m"]["rmse"].get<double>(), d, 1e-6);
  EXPECT_NEAR(j["ate_m"]["max"].get<double>(), d, 1e-6);
  EXPECT_NEAR(j["rpe_frames"]["trans_m"]["rmse"].get<double>(), 2 * d, 1e-6);
  EXPECT_NEAR(j["rpe_frames"]["trans_m"]["min"].get<double>(), 2 * d, 1e-6);
  EXPECT_LT(j["rpe_frames"]["rot_deg"]["max"].get<double>(), 1e-4);
  // With SE(3) alignment the zero-mean offset stays (alignment cannot absorb it).
  const ToolRun se3 = run("--gt " + gt_path + " --est " + path("alt.tum") + " --json " + path("s.json"));
  ASSERT_EQ(se3.exit_code, 0) << se3.output;
  EXPECT_NEAR(read_json("s.json")["trajectories"][0]["ate_m"]["rmse"].get<double>(), d, 1e-3);
  EXPECT_THAT(r.output, ::testing::HasSubstr("ATE_rmse"));
  std::ifstream svg(path("plot.svg"));
  std::string first;
  std::getline(svg, first);
  EXPECT_THAT(first, ::testing::StartsWith("<svg"));
}

TEST_F(CdcEvalTool, ScaleErrorShowsInKittiDriftAndSim3RemovesIt) {
  CDC_REQUIRE_KITTI(gt_path);
  Trajectory est = geometry::read_kitti(gt_path);
  for (auto& p : est) {
    p.pose.translation() *= 1.01;
  }
  geometry::write_kitti(path("scaled.txt"), est);
  const ToolRun r = run("--gt " + gt_path + " --est " + path("scaled.txt") + " --json " + path("out.json"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto j = read_json("out.json")["trajectories"][0];
  // Scaling every position by 1.01 makes each segment's error exactly 1 % of its chord (start to
  // end distance); the metric divides by the path length, so the expected figure is
  // 1 % x mean(chord / length) over the KITTI segments (starts every 10 frames, 100..800 m).
  const Trajectory gt = geometry::read_kitti(gt_path);
  std::vector<double> dist(gt.size(), 0.0);
  for (size_t i = 1; i < gt.size(); ++i) {
    dist[i] = dist[i - 1] + (gt[i].pose.translation() - gt[i - 1].pose.translation()).norm();
  }
  double ratio_sum = 0.0;
  size_t segments = 0;
  for (size_t first = 0; first < gt.size(); first += 10) {
    for (double len = 100; len <= 800; len += 100) {
      size_t last = first;
      while (last < gt.size() && dist[last] < dist[first] + len) {
        ++last;
      }
      if (last == gt.size()) {
        continue;
      }
      ratio_sum += (gt[last].pose.translation() - gt[first].pose.translation()).norm() / len;
      ++segments;
    }
  }
  EXPECT_EQ(j["kitti_drift"]["segments"].get<size_t>(), segments);
  EXPECT_NEAR(j["kitti_drift"]["trans_pct"].get<double>(), ratio_sum / static_cast<double>(segments), 1e-6);
  EXPECT_LT(j["kitti_drift"]["rot_deg_per_100m"].get<double>(), 1e-4);
  const ToolRun sim =
      run("--gt " + gt_path + " --est " + path("scaled.txt") + " --align sim3 --json " + path("s.json"));
  ASSERT_EQ(sim.exit_code, 0) << sim.output;
  const auto s = read_json("s.json")["trajectories"][0];
  EXPECT_LT(s["ate_m"]["rmse"].get<double>(), 1e-5);
  EXPECT_NEAR(s["alignment"]["scale"].get<double>(), 1.0 / 1.01, 1e-9);
}

TEST_F(CdcEvalTool, BadFileNamesFileAndLine) {
  {
    std::ofstream(path("gt.tum")) << "0.0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n0.2 2 0 0 0 0 0 1\n";
    std::ofstream(path("bad.tum")) << "0.0 0 0 0 0 0 0 1\n0.1 1 0 0 0 0 0 1\n0.2 2 0 zero 0 0 0 1\n";
  }
  const ToolRun r = run("--gt " + path("gt.tum") + " --est " + path("bad.tum"));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.output, ::testing::HasSubstr("bad.tum:3"));
  EXPECT_THAT(r.output, ::testing::HasSubstr("'zero' is not a finite number"));
  const ToolRun missing = run("--gt " + path("gt.tum") + " --est " + path("none.tum"));
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_THAT(missing.output, ::testing::HasSubstr("none.tum"));
  const ToolRun help = run("--help");
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_THAT(help.output, ::testing::HasSubstr("--gt"));
}

}  // namespace
}  // namespace cdc
