// frontend.yaml -> FrontendNodeOptions: the shipped file states the code's defaults, and a bad
// value or an unknown key is named in the error.
#include "../src/frontend_config.hpp"

#include "cdc/config/reader.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <filesystem>
#include <fstream>

namespace cdc::frontend {
namespace {

std::string write_yaml(const std::string& text) {
  const auto p =
      std::filesystem::temp_directory_path() / ("cdc-frontend-config-" + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

TEST(FrontendConfig, ShippedFileStatesTheDefaults) {
  const FrontendNodeOptions shipped = load_frontend_options(CDC_FRONTEND_YAML);
  const FrontendNodeOptions d = load_frontend_options("");
  const FrontendParams &a = shipped.core, &b = d.core;
  EXPECT_EQ(a.min_range_m, b.min_range_m);
  EXPECT_EQ(a.max_range_m, b.max_range_m);
  EXPECT_EQ(a.voxel_m, b.voxel_m);
  EXPECT_EQ(a.map.voxel_m, b.map.voxel_m);
  EXPECT_EQ(a.map.max_range_m, b.map.max_range_m);
  EXPECT_EQ(a.map.max_points, b.map.max_points);
  EXPECT_EQ(a.initial_gate_m, b.initial_gate_m);
  EXPECT_EQ(a.normal_voxel_m, b.normal_voxel_m);
  EXPECT_EQ(a.deskew, b.deskew);
  EXPECT_EQ(a.recovery.enabled, b.recovery.enabled);
  EXPECT_EQ(a.recovery.poor_fit_ratio, b.recovery.poor_fit_ratio);
  EXPECT_EQ(a.recovery.good_fit_ratio, b.recovery.good_fit_ratio);
  EXPECT_EQ(a.recovery.global, b.recovery.global);
  EXPECT_EQ(a.image_columns, b.image_columns);
  EXPECT_EQ(a.keyframe_distance_m, b.keyframe_distance_m);
  EXPECT_NEAR(a.keyframe_angle_rad, b.keyframe_angle_rad, 1e-4);
  EXPECT_EQ(a.keyframe_voxel_m, b.keyframe_voxel_m);
  EXPECT_EQ(a.keyframe_information_scale, b.keyframe_information_scale);
  EXPECT_EQ(a.information_scale, b.information_scale);
  EXPECT_EQ(a.fusion.pos_max, b.fusion.pos_max);
  EXPECT_NEAR(a.fusion.rot_max, b.fusion.rot_max, 1e-12);
  EXPECT_EQ(a.imu_window, b.imu_window);
  EXPECT_EQ(a.imu_deskew, b.imu_deskew);
  EXPECT_EQ(a.window.size, b.window.size);
  EXPECT_EQ(a.window.align_sweeps, b.window.align_sweeps);
  EXPECT_EQ(a.window.refine_gravity, b.window.refine_gravity);
  EXPECT_EQ(a.window.gravity_prior_sigma, b.window.gravity_prior_sigma);
  EXPECT_EQ(a.window.noise.gyro_noise, b.window.noise.gyro_noise);
  EXPECT_EQ(a.window.noise.accel_noise, b.window.noise.accel_noise);
  EXPECT_EQ(a.window.noise.gyro_bias_walk, b.window.noise.gyro_bias_walk);
  EXPECT_EQ(a.window.noise.accel_bias_walk, b.window.noise.accel_bias_walk);
  EXPECT_EQ(a.level_with_gravity, b.level_with_gravity);
  EXPECT_EQ(a.level_reference_sweeps, b.level_reference_sweeps);
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
  const std::string path = write_yaml(
      "crop:\n  max_range_m: -5\nregistration:\n  voxel: 1\nimu:\n  T_lidar_imu:\n    orientation: [0, 0, 0, 2]\n"
      "recovery:\n  good_fit_ratio: 1.5\n");
  try {
    load_frontend_options(path);
    ADD_FAILURE() << "no error";
  } catch (const config::ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("crop.max_range_m"), std::string::npos) << what;
    EXPECT_NE(what.find("registration.voxel"), std::string::npos) << what;
    EXPECT_NE(what.find("unit quaternion"), std::string::npos) << what;
    EXPECT_NE(what.find("recovery.good_fit_ratio"), std::string::npos) << what;
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace cdc::frontend
