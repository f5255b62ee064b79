// DDS shell of the front-end: the robot's LiDAR sweeps, IMU batches and the back-end's corrections
// in; odometry at scan rate, keyframes and lock-step progress out. The odometry is FrontendCore's.
#pragma once

#include "frontend_config.hpp"

#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <deque>
#include <optional>
#include <vector>

namespace cdc::frontend {

// The node's own counters beside the core's (FrontendStats).
struct FrontendNodeCounters {
  uint64_t odometry = 0, keyframes = 0;
  uint64_t corrections_for_unknown_keyframes = 0;
  uint64_t imu_gaps = 0;  // gaps over imu_gap_s, bridged by constant velocity
  uint64_t imu_late = 0;  // sweeps processed before the IMU reached their end (waited imu_wait)
};

class FrontendNode {
 public:
  FrontendNode(const runtime::ServiceOptions& common, const FrontendNodeOptions& options);
  // Works until shutdown is asked for.
  void spin();
  // Core and node counters, as --stats-out writes them.
  nlohmann::json stats() const;
  // Writes --trajectory-out and --stats-out.
  void finish() const;

 private:
  // A sweep taken in, waiting for the IMU to reach its end.
  struct PendingScan {
    int64_t stamp_ns = 0, end_ns = 0;
    uint64_t seq = 0;
    uint32_t incarnation = 0;
    std::chrono::steady_clock::time_point received;
    std::vector<ScanPoint> points;
  };

  void on_imu(const cdc_msg_ImuBatch& m);
  void on_correction(const cdc_msg_OptimizedPoses& m);
  void on_scan(const cdc_msg_LidarScan& m);
  dds::Validation check_scan(const cdc_msg_LidarScan& m) const;
  void on_sequence(const cdc_msg_KeyframeSequence& m);
  bool sequence_decided();
  void process_ready_scans();
  void log_registration_failure(const PendingScan& scan, const FrontendStats& before, const ScanOut& out) const;
  void publish(const PendingScan& scan, const ScanOut& out);
  void publish_keyframe(const KeyframeOut& k);

  FrontendNodeOptions o_;
  runtime::Service service_;
  runtime::Input<cdc_msg_LidarScan> scans_;
  runtime::Input<cdc_msg_ImuBatch> imu_;
  runtime::Input<cdc_msg_OptimizedPoses> corrections_;
  runtime::Input<cdc_msg_KeyframeSequence> sequence_;
  dds::TopicWriter<cdc_msg_Odometry> w_odom_;
  dds::TopicWriter<cdc_msg_Keyframe> w_kf_;
  dds::TopicWriter<cdc_msg_ConsumerProgress> w_progress_;

  FrontendCore core_;
  FrontendNodeCounters counters_;
  std::deque<PendingScan> pending_;
  int64_t last_scan_stamp_ = -1, last_imu_stamp_ = -1;
  uint32_t incarnation_ = 0;  // of the sweeps
  // The keyframe sequence this front-end numbers its keyframes in: its incarnation once decided.
  std::optional<uint32_t> sequence_incarnation_;
  std::optional<cdc_msg_KeyframeSequence> backend_sequence_;  // as the back-end last said
  const std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  geometry::Trajectory trajectory_;
  std::vector<cdc_msg_PointXYZI> cloud_;  // the keyframe cloud being published
};

}  // namespace cdc::frontend
