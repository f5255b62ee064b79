// The front-end's synchronous core: LiDAR(-inertial) odometry and keyframes for one robot, and the
// back-end's corrections taken in through adaptive pose fusion (CDC-SLAM eq. 8-14), so that the
// published trajectory never jumps.
//
// Each sweep passes through these stages, each its own class:
//   1. motion prediction (motion_prediction.hpp): the sliding-window IMU estimator's prediction
//      (imu_window.hpp), or constant velocity;
//   2. deskewing (deskewing.hpp): range crop, the sweep deskewed with the predicted motion, the
//      points registered and their normals;
//   3. scan-to-map registration (scan_to_map.hpp) against a voxel map that slides with the robot,
//      with the adaptive gate (adaptive_gate.hpp) and recovery (registration_recovery.hpp);
//   4. the map and the IMU window take the registered pose;
//   5. gravity levelling (gravity_levelling.hpp);
//   6. keyframe selection (keyframe_selection.hpp);
//   7. correction fusion (correction_fusion.hpp).
// The first sweep's motion is unknown when it arrives: once the second sweep tells it, the map is
// rebuilt from the first sweep deskewed, and its keyframe (held back until then) goes out deskewed.
#pragma once

#include "cdc/frontend/adaptive_gate.hpp"
#include "cdc/frontend/correction_fusion.hpp"
#include "cdc/frontend/deskewing.hpp"
#include "cdc/frontend/frontend_types.hpp"
#include "cdc/frontend/gravity_levelling.hpp"
#include "cdc/frontend/imu_buffer.hpp"
#include "cdc/frontend/imu_window.hpp"
#include "cdc/frontend/keyframe_selection.hpp"
#include "cdc/frontend/motion_prediction.hpp"
#include "cdc/frontend/scan_to_map.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <vector>

namespace cdc::frontend {

class FrontendCore {
 public:
  explicit FrontendCore(const FrontendParams& params);

  // IMU samples in time order (older ones than the last are ignored and counted by the caller).
  void add_imu(const ImuIn& sample);
  // Forgets the IMU history (after a gap): intervals it does not cover use constant velocity.
  void clear_imu() { imu_.clear(); }
  // One sweep; stamps strictly increasing (the caller validates).
  ScanOut process(int64_t stamp_ns, const std::vector<ScanPoint>& points);

  // Continues the robot's keyframe sequence held by its back-end (a restarted front-end, before its
  // first sweep): keyframe ids go on after `newest_id`, and the odometry frame is the sequence's, this
  // front-end's start placed at the newest keyframe's pose T_odom_newest. The first keyframe's relative
  // odometry is to that keyframe, with the weak information of FrontendParams::restart_link_sigma_*.
  void continue_sequence(uint32_t newest_id, const Eigen::Isometry3d& T_odom_newest);

  // A back-end result for a keyframe: its optimised pose in the world and T_world_robot. Later
  // scans move the published pose towards it, each by at most the fusion thresholds.
  bool set_correction(uint32_t keyframe_id, const Eigen::Isometry3d& T_world_keyframe,
                      const Eigen::Isometry3d& T_world_robot);

  const FrontendStats& stats() const noexcept { return stats_; }
  // The sliding window's latest IMU state (velocity, biases) and gravity, once it runs.
  std::optional<ImuState> imu_state() const { return predictor_.imu_state(); }
  std::optional<Eigen::Vector3d> gravity() const { return predictor_.gravity(); }
  size_t map_voxels() const noexcept { return map_.voxels(); }

 private:
  SweepIn sweep_in(int64_t stamp_ns, const std::vector<ScanPoint>& points) const;
  // The sweep deskewed with `motion` (since the previous sweep, scaled to the sweep's span).
  Sweep deskew(const SweepIn& in, const Eigen::Isometry3d& motion, const ImuStart* start) const;
  // The sweep's registered pose (map frame), or the prediction when registration fails.
  Eigen::Isometry3d locate(const SweepIn& in, const Prediction& prediction, Sweep& sweep, ScanOut& out);
  // On the second sweep: the map rebuilt from the first sweep deskewed with the motion `c` tells,
  // the held keyframe's cloud with it, and this sweep deskewed and registered again.
  void complete_first_sweep(const SweepIn& in, const RegistrationContext& ctx, Sweep& sweep, Candidate& c);
  void add_to_map(const std::vector<Eigen::Vector3d>& cloud, const Eigen::Isometry3d& T);
  void measure_motion(double dt, const Eigen::Isometry3d& T_map, const Eigen::Isometry3d& T_out, ScanOut& out);
  void fuse(const Eigen::Isometry3d& T_out, ScanOut& out);
  void end_sweep(const SweepIn& in, const Eigen::Isometry3d& T_map, const Eigen::Isometry3d& T_out, Sweep sweep);

  FrontendParams p_;
  odometry::VoxelMap map_;
  ImuBuffer imu_;
  MotionPredictor predictor_;
  Deskewer deskewer_;
  AdaptiveGate gate_;
  ScanToMapRegistration registration_;
  GravityLeveller leveller_;
  KeyframeSelector keyframes_;
  CorrectionFusion fusion_;
  FrontendStats stats_;
  bool first_ = true;
  int64_t last_stamp_ = 0;
  Eigen::Isometry3d T_last_ = Eigen::Isometry3d::Identity();      // registered (map frame)
  Eigen::Isometry3d T_out_last_ = Eigen::Isometry3d::Identity();  // levelled, from this front-end's start
  // The odometry frame L from this front-end's start frame: identity, or where the keyframe sequence
  // it continues stood.
  Eigen::Isometry3d T_odom_start_ = Eigen::Isometry3d::Identity();
  // The first sweep, kept until the second one tells its motion (only when it is deskewed).
  std::vector<ScanPoint> first_points_;
  int64_t first_stamp_ = 0;
};

}  // namespace cdc::frontend
