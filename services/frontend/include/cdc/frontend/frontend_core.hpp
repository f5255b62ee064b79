// The front-end's synchronous core: LiDAR(-inertial) odometry and keyframes for one robot, and the
// back-end's corrections taken in through adaptive pose fusion (CDC-SLAM eq. 8-14), so that the
// published trajectory never jumps.
//
// Per sweep: deskew (the bias-corrected IMU's rotation over the sweep when IMU samples are given,
// otherwise a constant-velocity model; a sweep whose points carry no times is taken as it is), range
// crop and voxel downsampling; scan-to-map registration against a voxel map that slides with the
// robot (common/odometry), started from the prediction of the sliding-window IMU estimator
// (imu_window.hpp: preintegration, biases, velocity; Ceres) or, until it runs, from constant
// velocity, with a correspondence gate that adapts to the prediction error; a registration that
// fails, slides or fits the map poorly recovered from other guesses (RecoveryParams); the pose
// levelled with the window's gravity (level_with_gravity); keyframes by travelled distance and
// rotation.
#pragma once

#include "cdc/frontend/imu_window.hpp"
#include "cdc/geometry/fusion.hpp"
#include "cdc/odometry/global_registration.hpp"
#include "cdc/odometry/imu_preintegration.hpp"
#include "cdc/odometry/registration.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <deque>
#include <memory>
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
  double min_gain = 0.05;  // a candidate replaces a plausible registration only if it fits this much better
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
  odometry::RegistrationParams registration;
  double initial_gate_m = 2.0;                    // correspondence gate until the motion model has history
  double min_gate_m = 0.3, max_gate_m = 2.0;
  double max_jump_rad = 0.35;                     // a registration this far (or max_gate_m) from its start is rejected
  double kernel_divisor = 9.0;                    // Geman-McClure scale = gate / this (KISS-ICP: 9)
  // Deskewing needs per-point times: a sweep whose points all carry time_offset 0 (a sensor without
  // them, motion-compensated or saved sweeps) is taken as it is whatever this says, and its first
  // keyframe goes out at once.
  bool deskew = true;
  bool redeskew = true;                           // deskew again with the registered motion, and refine
  int image_columns = 1800;                       // range-image width for normals (0.2 deg)
  double keyframe_distance_m = 1.0;               // LIO-SAM defaults
  double keyframe_angle_rad = 0.2;
  double keyframe_voxel_m = 0.4;                  // keyframe clouds (for loop closure and maps)
  // Registration Hessian -> information of a sweep's pose in the IMU window (LiDAR factors against
  // the IMU's preintegration).
  double information_scale = 20.0;
  // Registration Hessian -> information of the keyframes' relative odometry (the back-end's odometry
  // factors). Measured against the ground truth on the simulated KITTI 05 split with a miscalibrated
  // LiDAR: the window's 20 gave per-keyframe sigmas of 16-37 mm and 0.02-0.19 deg, 4-8 times the
  // actual errors (1.5-7.5 mm, 0.004-0.054 deg), so loops outweighed an odometry better than they
  // are. 200 keeps them on the safe side (sigmas 1.5-3 times the errors).
  double keyframe_information_scale = 200.0;
  geometry::FusionThresholds fusion{0.10, 1.0 * M_PI / 180.0};
  // With the odometry levelled with gravity, a back-end correction turns it only about its vertical
  // axis (the odometry frame's z); its roll and pitch stay the front-end's, which gravity observes
  // and a loop's registration only weakly. The corrected keyframe's position is taken whole. A
  // correction's tilt, applied to every later scan, moved the height by the tilt times the distance
  // driven since the keyframe (up to 16 cm within 20 s on the simulated KITTI 05 split).
  bool correction_holds_tilt = true;
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();  // extrinsic (IMU frame -> LiDAR frame)
  bool imu_window = true;                         // sliding-window IMU estimation when there is IMU
  // Deskew with the IMU's whole motion over the sweep (translation from the window's velocity, no
  // second deskew after registration) instead of its rotation with the translation of constant
  // velocity, deskewed again with the registered motion. Off: on the simulated KITTI 05 drive the
  // IMU's motion is the truer one (0.2 mm against 9 mm at the sweep's end from the true start
  // velocity), yet the odometry comes out slightly worse (ATE 0.29 against 0.27 m with VLP-16, 0.03
  // against 0.02 m with HDL-64E; drift alike), and 40-50 % faster.
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

// The IMU's increments (odometry::ImuDelta: in the IMU frame at `from`, gravity excluded) from
// `from` to each instant of `to` (ascending), in one pass over the bias-corrected samples (time
// order, sample-and-hold); none where the samples do not cover.
std::vector<std::optional<odometry::ImuDelta>> integrate_imu(const std::deque<ImuIn>& imu, int64_t from_ns,
                                                       const std::vector<int64_t>& to_ns, const Eigen::Vector3d& gyro_bias,
                                                       const Eigen::Vector3d& accel_bias);
// The IMU's velocity and gravity at the start of an increment, in its body frame there.
struct ImuStart {
  Eigen::Vector3d velocity = Eigen::Vector3d::Zero(), gravity = Eigen::Vector3d::Zero();
};
// The LiDAR's pose at the end of `inc` relative to its pose at the start: rotation and translation
// when the start is known, else the rotation alone (no translation).
Eigen::Isometry3d lidar_motion(const odometry::ImuDelta& inc, const Eigen::Isometry3d& T_lidar_imu, const ImuStart* start);

struct KeyframeOut {
  uint32_t id = 0;
  int64_t stamp_ns = 0;
  Eigen::Isometry3d T_odom_keyframe = Eigen::Isometry3d::Identity();  // raw odometry
  Eigen::Isometry3d T_prev = Eigen::Isometry3d::Identity();           // relative to keyframe id - 1
  Matrix6d information = Matrix6d::Identity();
  std::vector<Eigen::Vector3f> cloud;                                  // keyframe frame, deskewed
};

struct ScanOut {
  int64_t stamp_ns = 0;
  Eigen::Isometry3d T_odom_raw = Eigen::Isometry3d::Identity();   // the odometry itself
  Eigen::Isometry3d T_odom_base = Eigen::Isometry3d::Identity();  // with corrections fused in
  std::optional<Eigen::Isometry3d> T_world_base;                  // once T_world_robot is known
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();      // odometry frame [m/s]
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();     // sensor frame [rad/s]
  std::optional<KeyframeOut> keyframe;
  odometry::RegistrationOutput registration;
  odometry::FitQuality fit;                                       // of the registration taken (recovery.fit_*)
  bool recovered = false;                                         // the registration taken came from recovery
  double fusion_lambda = 1.0;                                     // eq. 12 for this scan (1: no limit)
  size_t points_used = 0;
};

struct FrontendStats {
  uint64_t scans = 0, keyframes = 0, registration_failures = 0, corrections = 0, corrections_levelled = 0, imu_samples = 0;
  uint64_t registration_rejected = 0;  // converged too far from where it started (counted in failures too)
  uint64_t imu_predictions = 0;        // sweeps predicted by the IMU window
  uint64_t imu_predictions_rejected = 0;  // ... whose prediction was implausible (constant velocity used)
  uint64_t imu_window_restarts = 0;    // IMU gaps and implausible window solutions
  uint64_t recovery_attempts = 0;      // sweeps whose fit was poor: registration retried from other guesses
  uint64_t recoveries = 0;             // ... and a retry fitted clearly better
  uint64_t recoveries_global = 0;      // ... the one taken started from the global registration
  double level_deg = 0, max_level_deg = 0;  // levelling rotation now and its largest [deg]
};

class FrontendCore {
 public:
  explicit FrontendCore(const FrontendParams& params);

  // IMU samples in time order (older ones than the last are ignored and counted by the caller).
  void add_imu(const ImuIn& sample);
  // Forgets the IMU history (after a gap): intervals it does not cover use constant velocity.
  void clear_imu() { imu_.clear(); }
  // One sweep; stamps strictly increasing (the caller validates).
  ScanOut process(int64_t stamp_ns, const std::vector<ScanPoint>& points);

  // A back-end result for a keyframe: its optimised pose in the world and T_world_robot. Later
  // scans move the published pose towards it, each by at most the fusion thresholds.
  bool set_correction(uint32_t keyframe_id, const Eigen::Isometry3d& T_world_keyframe,
                      const Eigen::Isometry3d& T_world_robot);

  const FrontendStats& stats() const noexcept { return stats_; }
  // The sliding window's latest IMU state (velocity, biases) and gravity, once it runs.
  std::optional<ImuState> imu_state() const;
  std::optional<Eigen::Vector3d> gravity() const;
  size_t map_voxels() const noexcept { return map_.voxels(); }

 private:
  // Deskews and crops a sweep: each point moved into the sensor frame at the sweep's start along
  // `sweep_motion` (constant velocity over the sweep), or the IMU's motion where the samples
  // cover: its rotation, and its translation too when `start` (the IMU window's state) is given.
  // A keyframe's cloud: a deskewed sweep, voxel-filtered to keyframe_voxel_m.
  std::vector<Eigen::Vector3f> keyframe_cloud(const std::vector<Eigen::Vector3d>& deskewed) const;
  std::vector<Eigen::Vector3d> prepare(int64_t stamp_ns, const std::vector<ScanPoint>& points, const Eigen::Isometry3d& sweep_motion,
                                       const ImuStart* start, std::vector<uint16_t>& rings) const;
  std::optional<Eigen::Matrix3d> imu_rotation(int64_t from_ns, int64_t to_ns) const;
  // The IMU's increments over [from, to] at the given biases; none where the samples do not cover.
  std::unique_ptr<odometry::ImuPreintegration> preintegrate(int64_t from_ns, int64_t to_ns, const Eigen::Vector3d& bg,
                                                            const Eigen::Vector3d& ba) const;
  void update_window(int64_t stamp_ns, const Eigen::Isometry3d& T, const odometry::RegistrationOutput& reg,
                     std::unique_ptr<odometry::ImuPreintegration> pre);
  // A sweep as it arrived.
  struct SweepIn {
    int64_t stamp_ns = 0;
    const std::vector<ScanPoint>* points = nullptr;
    float t_max = 0;   // latest point time [s]; 0: the sweep has no per-point times
    double dt = 0.1;   // since the previous sweep [s]
  };
  // A sweep made ready for registration: deskewed and cropped (sensor frame), and the points
  // registered (one per voxel_m voxel) with their normals.
  struct Sweep {
    std::vector<Eigen::Vector3d> cloud, points, normals;
  };
  // A registration of the sweep, how well it fits the map and the guess it started from.
  struct Candidate {
    odometry::RegistrationOutput reg;
    odometry::FitQuality fit;
    Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
  };
  // The motion since the previous sweep: the IMU window's, else constant velocity (with the IMU's
  // rotation where it covers). Sets `pre` (the IMU since the previous sweep) and `imu_start` (the
  // IMU's state at the sweep's start, for imu_deskew).
  Eigen::Isometry3d predict(int64_t stamp_ns, double dt, std::unique_ptr<odometry::ImuPreintegration>& pre,
                            std::optional<ImuStart>& imu_start);
  // The motion over a sweep's span t_max from the motion D over dt (constant velocity).
  static Eigen::Isometry3d motion_over(const Eigen::Isometry3d& D, float t_max, double dt);
  Sweep select(int64_t stamp_ns, const std::vector<ScanPoint>& points, const Eigen::Isometry3d& motion, const ImuStart* start) const;
  // The registration's gate and kernel, adapted to the prediction's recent errors (KISS-ICP).
  odometry::RegistrationParams adaptive_params() const;
  // Scan-to-map registration from `guess`, refined, recovered if poor, checked; the pose taken (the
  // guess when it fails). `sweep` may be deskewed again.
  Eigen::Isometry3d register_sweep(const SweepIn& in, const Eigen::Isometry3d& guess, bool imu_deskewed, Sweep& sweep, ScanOut& out);
  odometry::FitQuality fit_of(const Sweep& sweep, const odometry::RegistrationOutput& reg) const;
  // The median fit of the recent registrations; 0 while there are fewer than recovery.min_history.
  double recent_fit() const;
  // Whether a registration from `guess` needs recovery (RecoveryParams).
  bool poor_registration(const Eigen::Isometry3d& guess, const Candidate& c) const;
  // Registers again from other guesses (RecoveryParams); replaces `c` (and `sweep`, deskewed again
  // when `redeskew`) with a plausible registration that fits clearly better, if one is found.
  bool recover(const SweepIn& in, const Eigen::Isometry3d& guess, const odometry::RegistrationParams& rp, bool redeskew, Sweep& sweep,
               Candidate& c);
  // The registered pose T (map frame) in the published odometry frame (levelled with gravity).
  Eigen::Isometry3d level(const Eigen::Isometry3d& T);

  FrontendParams p_;
  odometry::VoxelMap map_;
  std::deque<ImuIn> imu_;
  std::unique_ptr<ImuWindow> window_;
  Eigen::Vector3d gyro_bias_ = Eigen::Vector3d::Zero();  // the window's latest estimate
  FrontendStats stats_;
  bool first_ = true;
  int64_t last_stamp_ = 0;
  Eigen::Isometry3d T_last_ = Eigen::Isometry3d::Identity();      // registered (map frame)
  Eigen::Isometry3d T_out_last_ = Eigen::Isometry3d::Identity();  // published odometry frame
  Eigen::Quaterniond level_ = Eigen::Quaterniond::Identity();     // map frame -> odometry frame (tilt)
  std::optional<Eigen::Vector3d> gravity_reference_, gravity_smoothed_;  // map frame, unit
  Eigen::Vector3d gravity_trend_ = Eigen::Vector3d::Zero();
  size_t level_sweeps_ = 0;
  Eigen::Isometry3d delta_ = Eigen::Isometry3d::Identity();  // last inter-scan motion
  double dt_last_ = 0.1;
  std::deque<double> model_errors_;
  std::deque<double> recent_fits_;  // fit (inlier fraction) of the last accepted registrations
  // Global registration in recovery: the previous sweep (sensor frame, as registered) and its
  // features once made; the sweep being processed and its features, if recovery made them.
  std::vector<Eigen::Vector3d> prev_cloud_;
  std::optional<odometry::FeatureCloud> prev_features_, current_features_;
  std::vector<ScanPoint> first_points_;  // kept until the second sweep tells their motion
  int64_t first_stamp_ = 0;
  // The first keyframe (the first sweep's), held back until the second sweep tells the first one's
  // motion and its cloud can be deskewed: sent undeskewed, it carried the sweep's motion (half a metre
  // at 10 m/s) into every loop verified against it (0.5 m loop errors on simulated KITTI 09).
  std::optional<KeyframeOut> held_first_keyframe_;
  // Keyframes.
  bool have_keyframe_ = false;
  uint32_t next_keyframe_ = 0;
  Eigen::Isometry3d T_last_keyframe_ = Eigen::Isometry3d::Identity();
  Matrix6d cov_since_keyframe_ = Matrix6d::Zero();
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> keyframe_poses_;  // odometry of every keyframe (uncorrected)
  // Fusion.
  Eigen::Isometry3d published_ = Eigen::Isometry3d::Identity();
  std::optional<Eigen::Isometry3d> correction_;  // maps raw odometry to the corrected odometry frame
  std::optional<Eigen::Isometry3d> T_world_robot_;
};

// Whether a converged registration is a step the robot can have made: within max_gate_m and
// max_jump_rad of the prediction. Beyond, it has slid into a wrong minimum (seen with miscalibrated
// LiDARs: 4.8 m down in one sweep) and the prediction is kept instead.
bool plausible_registration(const Eigen::Isometry3d& prediction, const Eigen::Isometry3d& registered,
                            const FrontendParams& p);

}  // namespace cdc::frontend
