// Pure helpers of the launcher's reports (no processes, no DDS).
#include "network.hpp"
#include "report.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>

namespace fs = std::filesystem;

namespace cdc::launch {
namespace {

class TempDir {
 public:
  TempDir() : path_(fs::temp_directory_path() / ("launch_report_test_" + std::to_string(::getpid()))) {
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  std::string file(const std::string& name) const { return (path_ / name).string(); }

 private:
  fs::path path_;
};

// A TUM trajectory along x at 10 Hz; from `from` on, every position is shifted by `dz` in z.
void write_tum(const std::string& path, int n, int from, double dz, double stamp_offset_s = 0) {
  std::ofstream out(path);
  out.precision(9);
  for (int i = 0; i < n; ++i) {
    out << 0.1 * i + stamp_offset_s << ' ' << 1.0 * i << " 0 " << (i >= from ? dz : 0.0) << " 0 0 0 1\n";
  }
}

TEST(PositionDifference, RmsAndLargestDistanceAtMatchingStamps) {
  TempDir dir;
  write_tum(dir.file("c.tum"), 100, 100, 0.0);
  write_tum(dir.file("d.tum"), 100, 75, 0.2);  // the last quarter moved up by 0.2 m
  const auto d = position_difference(dir.file("c.tum"), dir.file("d.tum"));
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->matched, 100u);
  EXPECT_NEAR(d->max_m, 0.2, 1e-9);
  EXPECT_NEAR(d->rms_m, 0.1, 1e-9);  // sqrt(0.25 * 0.04)
}

TEST(PositionDifference, IdenticalTrajectoriesDoNotDiffer) {
  TempDir dir;
  write_tum(dir.file("a.tum"), 50, 50, 0.0);
  const auto d = position_difference(dir.file("a.tum"), dir.file("a.tum"));
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->matched, 50u);
  EXPECT_EQ(d->rms_m, 0.0);
  EXPECT_EQ(d->max_m, 0.0);
}

TEST(PositionDifference, MissingFilesOrNoCommonStampsGiveNothing) {
  TempDir dir;
  write_tum(dir.file("a.tum"), 20, 20, 0.0);
  write_tum(dir.file("late.tum"), 20, 20, 0.0, 100.0);  // no stamp within 5 ms of a's
  EXPECT_FALSE(position_difference(dir.file("a.tum"), dir.file("missing.tum")).has_value());
  EXPECT_FALSE(position_difference(dir.file("missing.tum"), dir.file("a.tum")).has_value());
  EXPECT_FALSE(position_difference(dir.file("a.tum"), dir.file("late.tum")).has_value());
}

// Distributed traffic per keyframe on a robot-to-robot link: per own keyframe (sent; sent and received)
// and per keyframe made at either end, where the other robot's keyframes count too (the central's
// link counts only the robot's own).
TEST(Report, DistributedTrafficPerKeyframeOfBothEnds) {
  TempDir dir;
  RunInfo info;
  info.name = "traffic";
  info.run_dir = dir.file("run");
  fs::create_directories(info.run_dir);
  info.robots = {1, 2};
  info.traffic_measured = true;
  ModeTraffic& t1 = info.traffic[1];
  t1.keyframes["DISTRIBUTED"] = 10;
  t1.peer_keyframes["DISTRIBUTED"][2] = 30;
  t1.bytes["DISTRIBUTED"][2] = LinkBytes{20000, 60000, 0, 0};
  t1.bytes["DISTRIBUTED"][kCentralNode] = LinkBytes{100, 900, 0, 0};
  ModeTraffic& t2 = info.traffic[2];
  t2.keyframes["CENTRALIZED"] = 30;
  t2.peer_keyframes["CENTRALIZED"][1] = 10;
  t2.bytes["CENTRALIZED"][1] = LinkBytes{60000, 20000, 0, 0};
  const nlohmann::json j = write_report(info);
  const auto& link = j["robots"]["1"]["traffic"]["DISTRIBUTED"]["robot2"];
  EXPECT_DOUBLE_EQ(link["sent_bytes_per_keyframe"].get<double>(), 2000.0);
  EXPECT_DOUBLE_EQ(link["bytes_per_keyframe"].get<double>(), 8000.0);
  EXPECT_EQ(link["keyframes_both_ends"].get<uint64_t>(), 40u);
  EXPECT_DOUBLE_EQ(link["bytes_per_keyframe_both_ends"].get<double>(), 2000.0);
  const auto& central = j["robots"]["1"]["traffic"]["DISTRIBUTED"]["central"];
  EXPECT_EQ(central["keyframes_both_ends"].get<uint64_t>(), 10u);
  EXPECT_DOUBLE_EQ(central["bytes_per_keyframe_both_ends"].get<double>(), 100.0);
  // Only DISTRIBUTED counts for the headline figures.
  EXPECT_DOUBLE_EQ(j["traffic"]["max_distributed_bytes_per_keyframe_per_link"].get<double>(), 8000.0);
  EXPECT_DOUBLE_EQ(j["traffic"]["max_distributed_sent_bytes_per_own_keyframe_per_link"].get<double>(), 2000.0);
  EXPECT_DOUBLE_EQ(j["traffic"]["max_distributed_bytes_per_keyframe_both_ends_per_link"].get<double>(), 2000.0);
  std::ifstream md(fs::path(info.run_dir) / "report.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("| robot1 - robot2 | DISTRIBUTED | 20000 | 60000 | 0 | 10 | 2000 | 8000 | 40 | 2000 |"),
            std::string::npos);
}

TEST(Report, LoopClosureCountsAndLatencyPerRobot) {
  TempDir dir;
  RunInfo info;
  info.name = "loops";
  info.run_dir = dir.file("run");
  info.robots = {0, 1};
  fs::create_directories(fs::path(info.run_dir) / "robot_0");
  std::ofstream(fs::path(info.run_dir) / "robot_0" / "loop_closure.stats.json")
      << R"({"intra_accepted": 3, "inter_accepted": 41, "loop_latency_s": {"count": 44, "median": 0.84, "p90": 6.26, "max": 19.5}})";
  fs::create_directories(fs::path(info.run_dir) / "robot_2");
  std::ofstream(fs::path(info.run_dir) / "robot_2" / "loop_closure.stats.json")
      << R"({"intra_accepted": 0, "inter_accepted": 0, "loop_latency_s": {"count": 0, "median": 0, "p90": 0, "max": 0}})";
  info.robots.push_back(2);
  const nlohmann::json j = write_report(info);
  EXPECT_DOUBLE_EQ(j["robots"]["0"]["stats"]["loop_closure"]["loop_latency_s"]["p90"].get<double>(), 6.26);
  std::ifstream md(fs::path(info.run_dir) / "report.md");
  const std::string text((std::istreambuf_iterator<char>(md)), std::istreambuf_iterator<char>());
  const size_t at = text.find("## Loop closure");
  ASSERT_NE(at, std::string::npos) << text;
  const std::string section = text.substr(at, text.find("\n## ", at + 1) - at);
  EXPECT_NE(section.find("| 0 | 3 | 41 | 0.8 / 6.3 / 19.5 |"), std::string::npos) << section;
  EXPECT_EQ(section.find("| 1 |"), std::string::npos) << "robot 1 has no loop-closure stats: no row\n" << section;
  EXPECT_NE(section.find("| 2 | 0 | 0 | - (none published) |"), std::string::npos) << section;
}

// cdc-experiment's repeats: per robot the median of each figure over the runs that have it, the
// real-time ATE's range and every run's value; a single run stays as it is.
TEST(MergeRuns, MediansPerRobotOverTheRunsThatHaveThem) {
  auto row = [](double wall, double ate0, double kf0, std::optional<double> ate1) {
    nlohmann::json r{{"wall_s", wall}};
    r["robots"]["0"] = {
        {"ate_m", ate0}, {"rpe_m", 0.001}, {"length_m", 500.0}, {"keyframes_ate_m", kf0}, {"corrections", 10}};
    if (ate1) r["robots"]["1"] = {{"ate_m", *ate1}, {"rpe_m", 0.002}, {"length_m", 300.0}};
    return r;
  };
  const std::vector<nlohmann::json> rows = {row(100, 0.030, 0.020, 0.010), row(120, 0.010, 0.040, std::nullopt),
                                            row(110, 0.020, 0.030, 0.030)};
  const nlohmann::json m = merge_runs(rows);
  EXPECT_EQ(m["runs"].get<int>(), 3);
  EXPECT_DOUBLE_EQ(m["wall_s"].get<double>(), 110.0);
  EXPECT_DOUBLE_EQ(m["robots"]["0"]["ate_m"].get<double>(), 0.020);
  EXPECT_DOUBLE_EQ(m["robots"]["0"]["keyframes_ate_m"].get<double>(), 0.030);
  EXPECT_DOUBLE_EQ(m["robots"]["0"]["ate_m_min"].get<double>(), 0.010);
  EXPECT_DOUBLE_EQ(m["robots"]["0"]["ate_m_max"].get<double>(), 0.030);
  EXPECT_EQ(m["robots"]["0"]["ate_m_runs"].size(), 3u);
  EXPECT_EQ(m["robots"]["0"]["corrections"].get<uint64_t>(), 10u);
  // Robot 1 is in two runs only: the median of two is their mean.
  EXPECT_DOUBLE_EQ(m["robots"]["1"]["ate_m"].get<double>(), 0.020);
  EXPECT_FALSE(m["robots"]["1"].contains("keyframes_ate_m"));
  EXPECT_EQ(merge_runs({rows[1]}), rows[1]);
}

}  // namespace
}  // namespace cdc::launch
