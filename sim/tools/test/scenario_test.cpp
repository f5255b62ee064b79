#include "scenario.hpp"
#include "cdc/config/reader.hpp"
#include "temp_dir.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>

namespace cdc::sim {
namespace {

namespace fs = std::filesystem;

std::string data_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr ? env : "../shared/data";
}

std::string scenarios() { return std::getenv("CDC_SCENARIOS_DIR"); }

using test::read_file;

class ScenarioFiles : public test::TempDirTest {
 protected:
  ScenarioFiles() : TempDirTest("scenario", "CDC_SCENARIOS_DIR") {}
  std::string write(const std::string& name, const std::string& text) {
    std::ofstream(dir_ / name) << text;
    return (dir_ / name).string();
  }
};

TEST_F(ScenarioFiles, SameScenarioAndSeedGiveByteIdenticalDatasets) {
  const std::string sc = write("small.yaml",
                               "name: small\nseed: 3\ntrajectories:\n  source: procedural\n  pattern: crossing\n"
                               "  robots: 2\n  duration_s: 20\n  size_m: 60\nradio:\n  central_robot: 0\n");
  GenerateOptions g;
  g.max_scans = 3;
  const Scenario s = load_scenario(sc);
  const auto a = generate_dataset(s, sc, (dir_ / "a").string(), g);
  generate_dataset(s, sc, (dir_ / "b").string(), g);
  EXPECT_EQ(a.robots, 2u);
  EXPECT_EQ(a.scans, 6u);
  EXPECT_GT(a.points, 6u * 10000u);
  size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir_ / "a")) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), dir_ / "a");
    ASSERT_TRUE(fs::exists(dir_ / "b" / rel)) << rel;
    ASSERT_EQ(read_file(e.path()), read_file(dir_ / "b" / rel)) << rel << " differs";
    ++files;
  }
  EXPECT_EQ(files, 2u * (3 + 3 + 4) +
                       5);  // per robot: scans, point metadata, times/imu/gt/calib; radio x2, world, scenario, summary
  for (const char* f :
       {"robot_0/times.txt", "robot_0/imu.csv", "robot_0/groundtruth.tum", "robot_1/velodyne/000002.bin",
        "robot_1/velodyne_meta/000002.bin", "radio.csv", "radio_periods.csv", "world.json", "scenario.yaml"}) {
    EXPECT_TRUE(fs::exists(dir_ / "a" / f)) << f;
  }
  // The IMU agrees with the ground truth it was simulated from: at rest on the ground plane gravity
  // dominates (|f| near 9.8 m/s^2 give or take the driving accelerations), from the first sample on.
  {
    std::ifstream imu(dir_ / "a/robot_0/imu.csv");
    std::string line;
    std::getline(imu, line);
    int n = 0;
    while (std::getline(imu, line)) {
      double t, ax, ay, az, gx, gy, gz;
      ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &t, &ax, &ay, &az, &gx, &gy, &gz), 7);
      const double f = std::sqrt(ax * ax + ay * ay + az * az);
      EXPECT_GT(f, 7.0) << "sample " << n << " at t=" << t;
      EXPECT_LT(f, 13.0) << "sample " << n << " at t=" << t;
      ++n;
    }
    EXPECT_GT(n, 50);
  }
  // A different seed gives a different world and different scans.
  const std::string sc2 = write("small2.yaml", read_file(sc).replace(read_file(sc).find("seed: 3"), 7, "seed: 4"));
  generate_dataset(load_scenario(sc2), sc2, (dir_ / "c").string(), g);
  EXPECT_NE(read_file(dir_ / "a/robot_0/velodyne/000000.bin"), read_file(dir_ / "c/robot_0/velodyne/000000.bin"));
}

TEST_F(ScenarioFiles, TheLidarsCalibrationErrorIsAPerBeamSpreadPlusACommonBias) {
  const Scenario clean = load_scenario(write("clean.yaml", "lidar: vlp16\n"));
  EXPECT_TRUE(scenario_lidar(clean).elevation_error_deg.empty());
  const Scenario bias = load_scenario(write("bias.yaml", "lidar: vlp16\nlidar_elevation_bias_deg: 0.22\n"));
  const LidarModel b = scenario_lidar(bias);
  ASSERT_EQ(b.elevation_error_deg.size(), b.elevations_deg.size());
  for (double e : b.elevation_error_deg) EXPECT_DOUBLE_EQ(e, 0.22);
  // The spread is drawn from the seed; the bias shifts every beam of the same draw.
  const LidarModel spread = scenario_lidar(load_scenario(write("s.yaml", "seed: 3\nlidar_elevation_error_deg: 0.2\n")));
  const LidarModel both = scenario_lidar(
      load_scenario(write("sb.yaml", "seed: 3\nlidar_elevation_error_deg: 0.2\nlidar_elevation_bias_deg: -0.1\n")));
  ASSERT_EQ(spread.elevation_error_deg.size(), both.elevation_error_deg.size());
  double spread_sum = 0;
  for (size_t i = 0; i < both.elevation_error_deg.size(); ++i) {
    EXPECT_NEAR(both.elevation_error_deg[i], spread.elevation_error_deg[i] - 0.1, 1e-12);
    spread_sum += std::abs(spread.elevation_error_deg[i]);
  }
  EXPECT_GT(spread_sum, 0.0);
  EXPECT_THROW(load_scenario(write("big.yaml", "lidar_elevation_bias_deg: 3\n")), config::ConfigError);
}

TEST_F(ScenarioFiles, AzimuthAndRangeErrorsAreSeededPerBeamAndLeaveTheElevationDrawAlone) {
  const LidarModel clean = scenario_lidar(load_scenario(write("c.yaml", "seed: 3\nlidar_elevation_error_deg: 0.2\n")));
  EXPECT_TRUE(clean.azimuth_error_deg.empty());
  EXPECT_TRUE(clean.range_offset_m.empty());
  const std::string all =
      "seed: 3\nlidar_elevation_error_deg: 0.2\nlidar_azimuth_error_deg: 0.2\nlidar_range_offset_m: 0.02\n";
  const LidarModel a = scenario_lidar(load_scenario(write("a.yaml", all)));
  const LidarModel again = scenario_lidar(load_scenario(write("a2.yaml", all)));
  const LidarModel other = scenario_lidar(load_scenario(write("o.yaml", "seed: 4\nlidar_azimuth_error_deg: 0.2\n")));
  ASSERT_EQ(a.azimuth_error_deg.size(), a.elevations_deg.size());
  ASSERT_EQ(a.range_offset_m.size(), a.elevations_deg.size());
  EXPECT_EQ(a.elevation_error_deg, clean.elevation_error_deg);  // adding errors does not redraw the others
  EXPECT_EQ(a.azimuth_error_deg, again.azimuth_error_deg);      // the seed fixes the sensor
  EXPECT_NE(a.azimuth_error_deg, other.azimuth_error_deg);
  EXPECT_NE(a.azimuth_error_deg, a.elevation_error_deg);  // streams of their own
  double az_sq = 0, r_sq = 0;
  for (size_t i = 0; i < a.azimuth_error_deg.size(); ++i) {
    az_sq += a.azimuth_error_deg[i] * a.azimuth_error_deg[i];
    r_sq += a.range_offset_m[i] * a.range_offset_m[i];
  }
  // Sixteen draws: their spread is the sigma within a factor of two.
  EXPECT_GT(std::sqrt(az_sq / 16), 0.1);
  EXPECT_LT(std::sqrt(az_sq / 16), 0.4);
  EXPECT_GT(std::sqrt(r_sq / 16), 0.01);
  EXPECT_LT(std::sqrt(r_sq / 16), 0.04);
  EXPECT_THROW(load_scenario(write("bad_az.yaml", "lidar_azimuth_error_deg: -0.1\n")), config::ConfigError);
  EXPECT_THROW(load_scenario(write("bad_r.yaml", "lidar_range_offset_m: 0.5\n")), config::ConfigError);
}

TEST_F(ScenarioFiles, EachRobotCanCarryALidarOfItsOwn) {
  const Scenario shared =
      load_scenario(write("sh.yaml", "seed: 3\nlidar_azimuth_error_deg: 0.2\nlidar_elevation_error_deg: 0.2\n"));
  EXPECT_EQ(scenario_lidar(shared, 0).azimuth_error_deg, scenario_lidar(shared, 2).azimuth_error_deg);
  const Scenario own = load_scenario(write(
      "own.yaml", "seed: 3\nlidar_azimuth_error_deg: 0.2\nlidar_elevation_error_deg: 0.2\nlidar_per_robot: true\n"));
  const LidarModel r0 = scenario_lidar(own, 0), r1 = scenario_lidar(own, 1), r1_again = scenario_lidar(own, 1);
  EXPECT_NE(r0.azimuth_error_deg, r1.azimuth_error_deg);
  EXPECT_NE(r0.elevation_error_deg, r1.elevation_error_deg);
  EXPECT_EQ(r1.azimuth_error_deg, r1_again.azimuth_error_deg);  // a unit's errors are fixed by the seed
  EXPECT_NE(r0.azimuth_error_deg, scenario_lidar(shared, 0).azimuth_error_deg);
  EXPECT_THROW(load_scenario(write("bad_own.yaml", "lidar_per_robot: sometimes\n")), config::ConfigError);
}

TEST_F(ScenarioFiles, BadScenariosNameTheField) {
  const std::string bad =
      write("bad.yaml", "trajectories:\n  source: carla\n  robots: 0\nlidar: vlp32\nradio:\n  rnage_m: 3\n");
  try {
    load_scenario(bad);
    FAIL();
  } catch (const config::ConfigError& e) {
    const std::string m = e.what();
    EXPECT_THAT(m, ::testing::HasSubstr("trajectories.source"));
    EXPECT_THAT(m, ::testing::HasSubstr("trajectories.robots"));
    EXPECT_THAT(m, ::testing::HasSubstr("lidar"));
    EXPECT_THAT(m, ::testing::HasSubstr("radio.rnage_m: unknown setting"));
  }
  EXPECT_THROW(load_scenario((dir_ / "none.yaml").string()), config::ConfigError);
  // A KITTI scenario without the reference data names the missing path.
  const std::string k = write("k.yaml", "trajectories:\n  source: kitti\n  sequence: \"05\"\n");
  GenerateOptions g;
  g.data_dir = (dir_ / "no-data").string();
  EXPECT_THAT([&] { generate_dataset(load_scenario(k), k, (dir_ / "out").string(), g); },
              ::testing::ThrowsMessage<std::runtime_error>(::testing::HasSubstr("no-data/kitti/poses/05.txt")));
}

// A number that passes must be one the simulator can work with: every numeric key has a finite range, and the
// error names the key, the value and the range.
TEST_F(ScenarioFiles, NumbersOutsideTheirRangeAreRefusedWithTheRange) {
  const auto error_of = [&](const std::string& text) {
    try {
      load_scenario(write("range.yaml", text));
    } catch (const config::ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_THAT(error_of("duration_s: 1e12\n"),
              ::testing::HasSubstr("duration_s: 1e12 is invalid (expected in [0, 7200])"));
  EXPECT_THAT(error_of("trajectories:\n  source: procedural\n  duration_s: 1e12\n"),
              ::testing::HasSubstr("trajectories.duration_s: 1e12 is invalid (expected in [1, 7200])"));
  EXPECT_THAT(error_of("radio:\n  robot_range_m: .inf\n"),
              ::testing::HasSubstr("radio.robot_range_m: .inf is not a finite number"));
  EXPECT_THAT(error_of("imu_rate_hz: .nan\n"), ::testing::HasSubstr("imu_rate_hz: .nan is not a finite number"));
  EXPECT_THAT(error_of("radio:\n  central_id: 4000000000\n"),
              ::testing::HasSubstr("radio.central_id: 4000000000 is invalid (expected in [0, 254])"));
  EXPECT_THAT(error_of("trajectories:\n  source: procedural\n  robots: 64\n  duration_s: 7200\n"),
              ::testing::HasSubstr("link samples, more than the 2e+07 allowed"));
}

TEST_F(ScenarioFiles, EveryShippedScenarioTakesEachRobotOutOfRangeAtLeastTwice) {
  size_t checked = 0;
  for (const auto& e : fs::directory_iterator(scenarios())) {
    if (e.path().extension() != ".yaml") {
      continue;  // README and other files
    }
    const Scenario s = load_scenario(e.path().string());
    GenerateOptions g;
    g.data_dir = data_dir();
    if (s.source == "kitti" && !fs::exists(fs::path(data_dir()) / "kitti/poses" / (s.kitti_sequence + ".txt"))) {
      std::printf("%s: reference data absent, not checked\n", e.path().filename().c_str());
      continue;
    }
    const auto periods = scenario_radio_periods(s, g);
    std::map<uint32_t, int> out;
    for (const auto& p : periods) {
      if (p.b == s.central_id) out[p.a]++;
    }
    for (int r = 0; r < s.robots; ++r) {
      if (r == s.central_robot) continue;
      std::printf("%s: robot %d leaves the central's range %d times\n", s.name.c_str(), r,
                  out[static_cast<uint32_t>(r)]);
      EXPECT_GE(out[static_cast<uint32_t>(r)], 2) << s.name << " robot " << r;
    }
    ++checked;
  }
  EXPECT_GE(checked, 1u);
}

}  // namespace
}  // namespace cdc::sim
