// The front-end's parameters, its inputs and outputs per sweep, and its counters: what the core
// (frontend_core.hpp) and each of its stages share.
#pragma once

#include "cdc/frontend/imu_window.hpp"
#include "cdc/geometry/fusion.hpp"
#include "cdc/odometry/global_registration.hpp"
#include "cdc/odometry/registration.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <optional>
#include <vector>

namespace cdc::frontend {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Recovery of a registration that the prediction led astray (LiDAR-only at a low rate, hand-held or
// legged: a sharp turn leaves the prediction beyond the correspondence gate's reach, and the
// registration settles in a wrong minimum or slides; a start after standing still, with the gate
// shrunk to its minimum, does the same). A registration is poor when it failed, slid further than
// max_gate_m / max_jump_rad from the prediction, or fits the map clearly worse than the sweeps
// before it: its fit (the fraction of its points whose nearest map point lies within
// fit_distance_m and whose plane distance is below fit_inlier_m) under poor_fit_ratio times the
// median of the last fit_history sweeps' fits. A poor registration is tried again, coarse to fine
// (gates_m, then the adaptive gate), from the prediction, from the last pose (no motion) and, if
// neither fits as well as the recent sweeps (good_fit_ratio of their median), from a global
// registration of the sweep onto the previous one (features, no guess). The best fit is taken if it
// beats the registration from the prediction by min_gain and lies within max_gate_m / max_jump_rad
// of the guess it started from. The test is relative to the run's own fits, not a threshold for one
// sensor or scene; on the simulated drives (10 Hz, with or without IMU) it rarely fires.
struct RecoveryParams {
  bool enabled = true;
  double fit_distance_m = 1.0, fit_inlier_m = 0.1;
  double poor_fit_ratio = 0.75;
  size_t fit_history = 20;
  size_t min_history = 5;  // fewer fits than this: only failures and slides are poor
  std::vector<double> gates_m = {2.0, 1.0, 0.5};
  double min_gain = 0.05;       // a candidate replaces a plausible registration only if it fits this much better
  double good_fit_ratio = 0.9;  // a candidate fitting this fraction of the recent median ends the search
  // Also from a global registration (FPFH features, RANSAC) of the sweep onto the previous one.
  bool global = true;
  odometry::GlobalRegistrationParams global_params;
};

struct FrontendParams {
  double min_range_m = 1.5, max_range_m = 100.0;  // crop
  double voxel_m = 1.0;                           // downsampling of the points registered
  double map_voxel_m = 0.5;                       // downsampling of the points added to the map
  // Sweeps without rings (saved .bin files): reduced to one point per voxel of this size first [m],
  // for their normals (k nearest neighbours) and everything after (0: not reduced).
  double normal_voxel_m = 0.2;
  odometry::VoxelMapParams map;
  odometry::RegistrationSettings registration;
  double initial_gate_m = 2.0;  // correspondence gate until the motion model has history
  double min_gate_m = 0.3, max_gate_m = 2.0;
  double max_jump_rad = 0.35;   // a registration this far (or max_gate_m) from its start is rejected
  double kernel_divisor = 9.0;  // Geman-McClure scale = gate / this (KISS-ICP: 9)
  // Deskewing needs per-point times: a sweep whose points all carry time_offset 0 (a sensor without
  // them, motion-compensated or saved sweeps) is taken as it is whatever this says, and its first
  // keyframe goes out at once.
  bool deskew = true;
  bool redeskew = true;              // deskew again with the registered motion, and refine
  int image_columns = 1800;          // range-image width for normals (0.2 deg)
  double keyframe_distance_m = 1.0;  // LIO-SAM defaults
  double keyframe_angle_rad = 0.2;
  double keyframe_voxel_m = 0.4;  // keyframe clouds (for loop closure and maps)
  // A restarted front-end's first keyframe is tied to the newest keyframe its back-end holds as if
  // the robot had not moved since: how far it went during the restart is not measured, so the link
  // is weak (these sigmas), and loops place the new segment.
  double restart_link_sigma_m = 2.0;
  double restart_link_sigma_rad = 0.35;
  // Registration Hessian -> information of a sweep's pose in the IMU window (LiDAR factors against
  // the IMU's preintegration).
  double information_scale = 20.0;
  // Registration Hessian -> information of the keyframes' relative odometry (the back-end's odometry
  // factors). 200 keeps the per-keyframe sigmas on the safe side of the errors measured against the
  // ground truth (1.5-3 times them); the window's 20 makes them 4-8 times the errors, and loops then
  // outweigh an odometry better than they are (tests/bench/README.md).
  double keyframe_information_scale = 200.0;
  geometry::FusionThresholds fusion{0.10, 1.0 * M_PI / 180.0};
  // With the odometry levelled with gravity, a back-end correction turns it only about its vertical
  // axis (the odometry frame's z); its roll and pitch stay the front-end's, which gravity observes
  // and a loop's registration only weakly. The corrected keyframe's position is taken whole. A
  // correction's tilt, applied to every later scan, moves the height by the tilt times the distance
  // driven since the keyframe.
  bool correction_holds_tilt = true;
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();  // extrinsic (IMU frame -> LiDAR frame)
  bool imu_window = true;                                         // sliding-window IMU estimation when there is IMU
  // Deskew with the IMU's whole motion over the sweep (translation from the window's velocity, no
  // second deskew after registration) instead of its rotation with the translation of constant
  // velocity, deskewed again with the registered motion. Off: on the simulated KITTI 05 drive the
  // IMU's motion is the truer one, yet the odometry comes out slightly worse (tests/bench/README.md).
  bool imu_deskew = false;
  // Levelling with gravity (LiDAR-inertial): registration, the map and the IMU window live in the
  // map's own frame, whose roll and pitch can drift (a LiDAR with miscalibrated beam elevations sees
  // flat ground as a shallow cone, and scan-to-map registration tilts slowly: 3 deg over 800 m on
  // the degraded simulated KITTI 05); the window's gravity estimate turns with that drift. The
  // published odometry is the registered pose turned by the rotation that takes the window's gravity
  // (filtered: level_gain, level_trend_gain) back to its direction level_reference_sweeps sweeps
  // after the window first ran, with the registered increments composed in that frame: roll, pitch
  // and height stop following the map's tilt. The keyframes, their relative odometry and the
  // corrections are in the levelled frame. Needs window.refine_gravity (else gravity never turns).
  bool level_with_gravity = true;
  size_t level_reference_sweeps = 30;
  double level_gain = 0.1, level_trend_gain = 0.005;
  ImuWindowParams window;
  // An IMU prediction this far from the constant-velocity one is not used (a window gone wrong).
  double max_imu_prediction_gap_m = 1.0, max_imu_prediction_gap_rad = 0.2;
  RecoveryParams recovery;
};

struct ScanPoint {
  Eigen::Vector3f p;
  float time_offset = 0;  // [s] since the sweep stamp; 0 for every point: the sweep has no per-point times
  uint16_t ring = 0;      // beam index, 0 = lowest (normals on the range image); 0 for every point: no rings
};

struct ImuIn {
  int64_t stamp_ns = 0;
  Eigen::Vector3d gyro = Eigen::Vector3d::Zero();   // [rad/s], IMU frame
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();  // [m/s^2], IMU frame
};

struct KeyframeOut {
  uint32_t id = 0;
  int64_t stamp_ns = 0;
  Eigen::Isometry3d T_odom_keyframe = Eigen::Isometry3d::Identity();  // raw odometry
  Eigen::Isometry3d T_prev = Eigen::Isometry3d::Identity();           // relative to keyframe id - 1
  Matrix6d information = Matrix6d::Identity();
  std::vector<Eigen::Vector3f> cloud;  // keyframe frame, deskewed
};

struct ScanOut {
  int64_t stamp_ns = 0;
  Eigen::Isometry3d T_odom_raw = Eigen::Isometry3d::Identity();   // the odometry itself
  Eigen::Isometry3d T_odom_base = Eigen::Isometry3d::Identity();  // with corrections fused in
  std::optional<Eigen::Isometry3d> T_world_base;                  // once T_world_robot is known
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();      // odometry frame [m/s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();     // sensor frame [rad/s]
  std::optional<KeyframeOut> keyframe;
  odometry::RegistrationResult registration;
  odometry::FitQuality fit;    // of the registration taken (recovery.fit_*)
  bool recovered = false;      // the registration taken came from recovery
  double fusion_lambda = 1.0;  // eq. 12 for this scan (1: no limit)
  size_t points_used = 0;
};

struct FrontendStats {
  uint64_t scans = 0, keyframes = 0, registration_failures = 0, corrections = 0, corrections_levelled = 0,
           imu_samples = 0;
  uint64_t registration_rejected = 0;       // converged too far from where it started (counted in failures too)
  uint64_t imu_predictions = 0;             // sweeps predicted by the IMU window
  uint64_t imu_predictions_rejected = 0;    // ... whose prediction was implausible (constant velocity used)
  uint64_t imu_window_restarts = 0;         // IMU gaps and implausible window solutions
  uint64_t recovery_attempts = 0;           // sweeps whose fit was poor: registration retried from other guesses
  uint64_t recoveries = 0;                  // ... and a retry fitted clearly better
  uint64_t recoveries_global = 0;           // ... the one taken started from the global registration
  double level_deg = 0, max_level_deg = 0;  // levelling rotation now and its largest [deg]
};

}  // namespace cdc::frontend
