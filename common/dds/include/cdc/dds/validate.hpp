// Validation of every sample at the node boundary. Each check returns a reason instead of
// throwing, so a node can log it, count it and carry on.
#pragma once

#include "cdc/dds/types.hpp"

#include <cstdint>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

namespace cdc::dds {

struct ValidationLimits {
  uint32_t robot_count = 16;             // robot ids must be < robot_count (at most 255)
  std::vector<uint32_t> extra_node_ids;  // other node ids accepted (e.g. a ground-station central)
  double quaternion_tolerance = 1e-3;    // |1 - |q|| allowed
  uint32_t max_scan_points = 2'000'000;
  uint32_t max_cloud_points = 500'000;  // keyframe clouds and cloud replies
  uint32_t max_imu_samples = 10'000;
  uint32_t max_descriptor_cells = 65'536;
  uint32_t max_poses = 1'000'000;  // poses in one optimiser result
};

// ok() or the reason a sample is rejected.
class Validation {
 public:
  static Validation ok() { return Validation{}; }
  static Validation fail(std::string reason) {
    Validation v;
    v.reason_ = std::move(reason);
    v.ok_ = false;
    return v;
  }
  explicit operator bool() const noexcept { return ok_; }
  bool is_ok() const noexcept { return ok_; }
  const std::string& reason() const noexcept { return reason_; }

 private:
  bool ok_ = true;
  std::string reason_;
};

Validation validate_pose(const cdc_msg_Pose& pose, std::string_view field, const ValidationLimits& limits);
Validation validate_pose(const cdc_msg_PoseF& pose, std::string_view field, const ValidationLimits& limits);
Validation validate_information(const cdc_msg_Information6& info, std::string_view field);
Validation validate_robot_id(uint32_t id, std::string_view field, const ValidationLimits& limits);

Validation validate(const cdc_msg_LidarScan& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_ImuBatch& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_Odometry& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_Keyframe& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_KeyframeCloud& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_Descriptor& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_LoopClosure& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_CloudRequest& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_DescriptorSync& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_CloudReply& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_OptimizedPoses& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_SeparatorPoses& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_WorldTransform& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_KeyframeSequence& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_ModeState& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_RobotStatus& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_Acknowledgement& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_GroundTruth& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_RadioState& m, const ValidationLimits& limits);
Validation validate(const cdc_msg_ConsumerProgress& m, const ValidationLimits& limits);

// Thread-safe tally of rejected samples per topic, for logs and run reports.
class RejectionCounter {
 public:
  // Records a rejection (no-op for an ok validation); returns true when it was a rejection.
  bool record(std::string_view topic, const Validation& v);
  uint64_t total() const;
  uint64_t count(std::string_view topic) const;
  std::map<std::string, uint64_t> by_topic() const;
  std::string last_reason() const;

 private:
  mutable std::mutex mutex_;
  std::map<std::string, uint64_t, std::less<>> counts_;
  uint64_t total_ = 0;
  std::string last_reason_;
};

}  // namespace cdc::dds
