#include "frontend_config.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/geometry/se3.hpp"

#include <cmath>
#include <vector>

namespace cdc::frontend {
namespace {

bool positive(const double& v) { return v > 0; }
bool non_negative(const double& v) { return v >= 0; }
bool fraction(const double& v) { return v > 0 && v <= 1; }

// Crop, registration, deskewing and recovery.
void read_registration(config::Reader& r, FrontendParams& p) {
  r.get<double>("crop.min_range_m", p.min_range_m, non_negative, ">= 0");
  r.get<double>("crop.max_range_m", p.max_range_m, positive, "> 0");
  r.get<double>("registration.voxel_m", p.voxel_m, positive, "> 0");
  r.get<double>("registration.map_voxel_m", p.map.voxel_m, positive, "> 0");
  r.get<double>("registration.map_range_m", p.map.max_range_m, positive, "> 0");
  r.get<int>(
      "registration.map_points_per_voxel", p.map.max_points, [](const int& v) { return v > 0; }, "> 0");
  r.get<double>("registration.initial_gate_m", p.initial_gate_m, positive, "> 0");
  r.get<double>("registration.normal_voxel_m", p.normal_voxel_m, non_negative, ">= 0");
  r.get<bool>("deskew", p.deskew);
  r.get<bool>("recovery.enabled", p.recovery.enabled);
  r.get<double>("recovery.poor_fit_ratio", p.recovery.poor_fit_ratio, fraction, "in (0, 1]");
  r.get<double>("recovery.good_fit_ratio", p.recovery.good_fit_ratio, fraction, "in (0, 1]");
  r.get<bool>("recovery.global", p.recovery.global);
  r.get<int>(
      "image_columns", p.image_columns, [](const int& v) { return v >= 100; }, ">= 100");
}

// Keyframes and fusion; the angles in degrees, as the file gives them.
struct Degrees {
  double keyframe, fusion;
};
Degrees read_keyframes_and_fusion(config::Reader& r, FrontendParams& p) {
  Degrees deg{p.keyframe_angle_rad * 180 / M_PI, p.fusion.rot_max * 180 / M_PI};
  r.get<double>("keyframe.distance_m", p.keyframe_distance_m, positive, "> 0");
  r.get<double>("keyframe.angle_deg", deg.keyframe, positive, "> 0");
  r.get<double>("keyframe.voxel_m", p.keyframe_voxel_m, positive, "> 0");
  r.get<double>("keyframe.information_scale", p.keyframe_information_scale, positive, "> 0");
  r.get<double>("imu.window.information_scale", p.information_scale, positive, "> 0");
  r.get<double>("fusion.pos_max_m", p.fusion.pos_max, positive, "> 0");
  r.get<double>("fusion.rot_max_deg", deg.fusion, positive, "> 0");
  r.get<bool>("fusion.hold_tilt", p.correction_holds_tilt);
  return deg;
}

// The IMU, its sliding window and levelling.
void read_imu(config::Reader& r, FrontendNodeOptions& o) {
  FrontendParams& p = o.core;
  r.get<bool>("imu.use", o.use_imu);
  r.get<double>("imu.gap_s", o.imu_gap_s, positive, "> 0");
  r.get<bool>("imu.window.enabled", p.imu_window);
  r.get<bool>("imu.window.deskew", p.imu_deskew);
  r.get<bool>("imu.window.refine_gravity", p.window.refine_gravity);
  r.get<double>("imu.window.gravity_prior_sigma", p.window.gravity_prior_sigma, positive, "> 0");
  int window = static_cast<int>(p.window.size), align = static_cast<int>(p.window.align_sweeps);
  r.get<int>(
      "imu.window.size", window, [](const int& v) { return v >= 2 && v <= 100; }, "2..100");
  r.get<int>(
      "imu.window.align_sweeps", align, [](const int& v) { return v >= 3 && v <= 1000; }, "3..1000");
  r.get<double>("imu.window.gyro_noise", p.window.noise.gyro_noise, positive, "> 0");
  r.get<double>("imu.window.accel_noise", p.window.noise.accel_noise, positive, "> 0");
  r.get<double>("imu.window.gyro_bias_walk", p.window.noise.gyro_bias_walk, positive, "> 0");
  r.get<double>("imu.window.accel_bias_walk", p.window.noise.accel_bias_walk, positive, "> 0");
  p.window.size = static_cast<size_t>(window);
  p.window.align_sweeps = static_cast<size_t>(align);
  r.get<bool>("imu.level_with_gravity", p.level_with_gravity);
  int level_sweeps = static_cast<int>(p.level_reference_sweeps);
  r.get<int>(
      "imu.level_reference_sweeps", level_sweeps, [](const int& v) { return v >= 1; }, ">= 1");
  p.level_reference_sweeps = static_cast<size_t>(level_sweeps);
}

}  // namespace

FrontendNodeOptions load_frontend_options(const std::string& path) {
  FrontendNodeOptions o;
  config::Reader r(path);
  int robots = static_cast<int>(o.robots);
  r.get<int>(
      "robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.robots = static_cast<uint32_t>(robots);
  read_registration(r, o.core);
  const Degrees deg = read_keyframes_and_fusion(r, o.core);
  read_imu(r, o);
  std::vector<double> t = {0, 0, 0}, q = {0, 0, 0, 1};
  r.get<std::vector<double>>(
      "imu.T_lidar_imu.position", t, [](const std::vector<double>& v) { return v.size() == 3; }, "3 numbers");
  r.get<std::vector<double>>(
      "imu.T_lidar_imu.orientation", q, [](const std::vector<double>& v) { return v.size() == 4; },
      "4 numbers (x, y, z, w)");
  r.get<std::string>("log_level", o.log_level);
  const Eigen::Quaterniond quat(q[3], q[0], q[1], q[2]);
  if (std::abs(quat.norm() - 1.0) > 1e-3) r.error("imu.T_lidar_imu.orientation: not a unit quaternion");
  r.finish();
  o.core.keyframe_angle_rad = deg.keyframe * M_PI / 180;
  o.core.fusion.rot_max = deg.fusion * M_PI / 180;
  o.core.T_lidar_imu = geometry::make_pose(Eigen::Vector3d(t[0], t[1], t[2]), quat.normalized());
  return o;
}

}  // namespace cdc::frontend
