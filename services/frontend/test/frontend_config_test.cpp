// frontend.yaml -> FrontendNodeOptions: the shipped file states the code's defaults, and a bad
// value or an unknown key is named in the error.
#include "../src/frontend_config.hpp"

#include "cdc/config/reader.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <tuple>

namespace cdc::frontend {
namespace {

std::string write_yaml(const std::string& text) {
  const auto p =
      std::filesystem::temp_directory_path() / ("cdc-frontend-config-" + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

// Loading YAML fails with a ConfigError whose message holds each of the parts.
void expect_refused(const std::string& yaml, std::initializer_list<const char*> parts) {
  const std::string path = write_yaml(yaml);
  try {
    load_frontend_options(path);
    ADD_FAILURE() << "no error";
  } catch (const config::ConfigError& e) {
    const std::string what = e.what();
    for (const char* part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
  }
  std::filesystem::remove(path);
}

TEST(FrontendConfig, ShippedFileStatesTheDefaults) {
  const FrontendNodeOptions shipped = load_frontend_options(CDC_FRONTEND_YAML);
  const FrontendNodeOptions d = load_frontend_options("");
  const FrontendParams &a = shipped.core, &b = d.core;
  // Every setting but the two angles, compared exactly (as one tuple: gtest prints both when they differ).
  const auto exact = [](const FrontendParams& p) {
    return std::tie(
        p.min_range_m, p.max_range_m, p.voxel_m, p.map.voxel_m, p.map.max_range_m, p.map.max_points, p.initial_gate_m,
        p.normal_voxel_m, p.deskew, p.recovery.enabled, p.recovery.poor_fit_ratio, p.recovery.good_fit_ratio,
        p.recovery.global, p.image_columns, p.keyframe_distance_m, p.keyframe_voxel_m, p.keyframe_information_scale,
        p.information_scale, p.fusion.pos_max, p.imu_window, p.imu_deskew, p.window.size, p.window.align_sweeps,
        p.window.refine_gravity, p.window.gravity_prior_sigma, p.window.noise.gyro_noise, p.window.noise.accel_noise,
        p.window.noise.gyro_bias_walk, p.window.noise.accel_bias_walk, p.level_with_gravity, p.level_reference_sweeps);
  };
  EXPECT_EQ(exact(a), exact(b));
  EXPECT_NEAR(a.keyframe_angle_rad, b.keyframe_angle_rad, 1e-4);
  EXPECT_NEAR(a.fusion.rot_max, b.fusion.rot_max, 1e-12);
  EXPECT_EQ(shipped.use_imu, d.use_imu);
  EXPECT_EQ(shipped.imu_gap_s, d.imu_gap_s);
  EXPECT_EQ(shipped.robots, d.robots);
  // The one setting that is not a default: the simulator's IMU extrinsic (sim/, calib.yaml).
  EXPECT_TRUE(a.T_lidar_imu.translation().isApprox(Eigen::Vector3d(-0.1, 0, -0.05)));
}

TEST(FrontendConfig, ValuesAreRead) {
  const std::string path = write_yaml(
      "crop:\n  max_range_m: 60\nkeyframe:\n  angle_deg: 30\nimu:\n  use: false\n"
      "recovery:\n  enabled: false\n  poor_fit_ratio: 0.6\n  global: false\n");
  const FrontendNodeOptions o = load_frontend_options(path);
  std::filesystem::remove(path);
  EXPECT_EQ(o.core.max_range_m, 60);
  EXPECT_NEAR(o.core.keyframe_angle_rad, 30 * M_PI / 180, 1e-12);
  EXPECT_FALSE(o.use_imu);
  EXPECT_FALSE(o.core.recovery.enabled);
  EXPECT_EQ(o.core.recovery.poor_fit_ratio, 0.6);
  EXPECT_FALSE(o.core.recovery.global);
}

TEST(FrontendConfig, BadValuesAndUnknownKeysAreNamed) {
  expect_refused(
      "crop:\n  max_range_m: -5\nregistration:\n  voxel: 1\nimu:\n  T_lidar_imu:\n    orientation: [0, 0, 0, 2]\n"
      "recovery:\n  good_fit_ratio: 1.5\n",
      {"crop.max_range_m", "registration.voxel", "unit quaternion", "recovery.good_fit_ratio"});
}

// Values that pass must work: each numeric key has a finite range, a crop must keep something, and the error
// names the key, the value and the range.
TEST(FrontendConfig, ValuesThatCannotWorkAreRefusedWithTheirRange) {
  expect_refused(
      "crop:\n  min_range_m: 50\n  max_range_m: 40\nregistration:\n  voxel_m: 1e-9\nimage_columns: 1000000000\n"
      "fusion:\n  pos_max_m: .inf\n",
      {"registration.voxel_m: 1e-9 is invalid (expected in [0.01, 10])",
       "image_columns: 1000000000 is invalid (expected in [100, 10000])",
       "crop.min_range_m must be below crop.max_range_m", "fusion.pos_max_m: .inf is not a finite number"});
}

}  // namespace
}  // namespace cdc::frontend
