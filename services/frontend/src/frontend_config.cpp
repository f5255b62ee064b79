#include "frontend_config.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/geometry/se3.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace cdc::frontend {
namespace {

// Crop, registration, deskewing and recovery.
void read_registration(config::Reader& r, FrontendParams& p) {
  r.get_in("crop.min_range_m", p.min_range_m, 0.0, 100.0);
  r.get_in("crop.max_range_m", p.max_range_m, 1.0, 1000.0);
  if (p.min_range_m >= p.max_range_m) r.error("crop.min_range_m must be below crop.max_range_m");
  r.get_in("registration.voxel_m", p.voxel_m, 0.01, 10.0);
  r.get_in("registration.map_voxel_m", p.map.voxel_m, 0.01, 10.0);
  r.get_in("registration.map_range_m", p.map.max_range_m, 1.0, 1000.0);
  r.get_in("registration.map_points_per_voxel", p.map.max_points, 1, 1000);
  r.get_in("registration.initial_gate_m", p.initial_gate_m, 0.01, 100.0);
  r.get_in("registration.normal_voxel_m", p.normal_voxel_m, 0.0, 10.0);
  r.get<bool>("deskew", p.deskew);
  r.get<bool>("recovery.enabled", p.recovery.enabled);
  r.get_in("recovery.poor_fit_ratio", p.recovery.poor_fit_ratio, 0.001, 1.0);
  r.get_in("recovery.good_fit_ratio", p.recovery.good_fit_ratio, 0.001, 1.0);
  r.get<bool>("recovery.global", p.recovery.global);
  r.get_in("image_columns", p.image_columns, 100, 10000);
}

// Keyframes and fusion; the angles in degrees, as the file gives them.
struct Degrees {
  double keyframe, fusion;
};
Degrees read_keyframes_and_fusion(config::Reader& r, FrontendParams& p) {
  Degrees deg{p.keyframe_angle_rad * 180 / M_PI, p.fusion.rot_max * 180 / M_PI};
  r.get_in("keyframe.distance_m", p.keyframe_distance_m, 0.01, 1000.0);
  r.get_in("keyframe.angle_deg", deg.keyframe, 0.1, 180.0);
  r.get_in("keyframe.voxel_m", p.keyframe_voxel_m, 0.01, 10.0);
  r.get_in("keyframe.information_scale", p.keyframe_information_scale, 1e-6, 1e6);
  r.get_in("imu.window.information_scale", p.information_scale, 1e-6, 1e6);
  r.get_in("fusion.pos_max_m", p.fusion.pos_max, 0.001, 1000.0);
  r.get_in("fusion.rot_max_deg", deg.fusion, 0.01, 180.0);
  r.get<bool>("fusion.hold_tilt", p.correction_holds_tilt);
  return deg;
}

// The IMU, its sliding window and levelling.
void read_imu(config::Reader& r, FrontendNodeOptions& o) {
  FrontendParams& p = o.core;
  r.get<bool>("imu.use", o.use_imu);
  r.get_in("imu.gap_s", o.imu_gap_s, 0.001, 10.0);
  r.get<bool>("imu.window.enabled", p.imu_window);
  r.get<bool>("imu.window.deskew", p.imu_deskew);
  r.get<bool>("imu.window.refine_gravity", p.window.refine_gravity);
  r.get_in("imu.window.gravity_prior_sigma", p.window.gravity_prior_sigma, 1e-9, 100.0);
  r.get_count("imu.window.size", p.window.size, 2, 100);
  r.get_count("imu.window.align_sweeps", p.window.align_sweeps, 3, 1000);
  r.get_in("imu.window.gyro_noise", p.window.noise.gyro_noise, 1e-12, 100.0);
  r.get_in("imu.window.accel_noise", p.window.noise.accel_noise, 1e-12, 100.0);
  r.get_in("imu.window.gyro_bias_walk", p.window.noise.gyro_bias_walk, 1e-12, 100.0);
  r.get_in("imu.window.accel_bias_walk", p.window.noise.accel_bias_walk, 1e-12, 100.0);
  r.get<bool>("imu.level_with_gravity", p.level_with_gravity);
  r.get_count("imu.level_reference_sweeps", p.level_reference_sweeps, 1, 100000);
}

}  // namespace

FrontendNodeOptions load_frontend_options(const std::string& path) {
  FrontendNodeOptions o;
  config::Reader r(path);
  r.get_count("robots", o.robots, 1, 254);
  read_registration(r, o.core);
  const Degrees deg = read_keyframes_and_fusion(r, o.core);
  read_imu(r, o);
  std::vector<double> t = {0, 0, 0}, q = {0, 0, 0, 1};
  r.get<std::vector<double>>(
      "imu.T_lidar_imu.position", t,
      [](const std::vector<double>& v) {
        return v.size() == 3 && std::all_of(v.begin(), v.end(), [](double x) { return std::abs(x) <= 100; });
      },
      "3 numbers, each in [-100, 100] m");
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
