#include "cdc/dds/validate.hpp"

#include "cdc/dds/compact.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

namespace cdc::dds {
namespace {

std::string num(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

std::string cat(std::string_view a, std::string_view b) {
  std::string s(a);
  s += b;
  return s;
}

bool finite(double v) { return std::isfinite(v); }

// Declared element count against the sequence actually received, and a size limit.
template <class Seq>
Validation check_sequence(const Seq& seq, uint32_t declared, uint32_t max, std::string_view field) {
  if (seq._length > 0 && seq._buffer == nullptr) {
    return Validation::fail(cat(field, ": length " + std::to_string(seq._length) + " but no buffer"));
  }
  if (seq._length != declared) {
    return Validation::fail(cat(field, ": declared " + std::to_string(declared) + " elements but " +
                                           std::to_string(seq._length) + " received (length mismatch)"));
  }
  if (seq._length > max) {
    return Validation::fail(
        cat(field, ": " + std::to_string(seq._length) + " elements exceed the limit of " + std::to_string(max)));
  }
  return Validation::ok();
}

template <class Seq>
Validation check_sequence_max(const Seq& seq, uint32_t max, std::string_view field) {
  return check_sequence(seq, seq._length, max, field);
}

template <class P>
Validation check_points(const P* pts, uint32_t n, std::string_view field) {
  for (uint32_t i = 0; i < n; ++i) {
    const auto& p = pts[i];
    if (!finite(p.x) || !finite(p.y) || !finite(p.z) || !finite(p.intensity)) {
      return Validation::fail(cat(field, "[" + std::to_string(i) + "]: non-finite coordinate or intensity (NaN/Inf)"));
    }
  }
  return Validation::ok();
}

Validation check_finite(double v, std::string_view field) {
  if (!finite(v)) {
    return Validation::fail(cat(field, ": not a finite number (" + num(v) + ")"));
  }
  return Validation::ok();
}

template <class Vec>
Validation check_vec3(const Vec& v, std::string_view field) {
  if (!finite(v.x) || !finite(v.y) || !finite(v.z)) {
    return Validation::fail(
        cat(field, ": non-finite component (" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + ")"));
  }
  return Validation::ok();
}

bool known_node(uint32_t id, const ValidationLimits& limits) {
  return std::find(limits.extra_node_ids.begin(), limits.extra_node_ids.end(), id) != limits.extra_node_ids.end();
}

Validation check_node_id(uint32_t id, std::string_view field, const ValidationLimits& limits) {
  if (known_node(id, limits)) {
    return Validation::ok();
  }
  return validate_robot_id(id, field, limits);
}

template <class E>
Validation check_enum(const E& field_ref, int count, std::string_view field) {
  // Read the raw 32-bit value (as deserialised off the wire): loading an out-of-range value as the
  // enum type itself would be undefined behaviour.
  static_assert(sizeof(E) == sizeof(int32_t), "IDL enums are 32-bit");
  int32_t i = 0;
  std::memcpy(&i, &field_ref, sizeof i);
  if (i < 0 || i >= count) {
    return Validation::fail(cat(field, ": unknown enumerator " + std::to_string(i)));
  }
  return Validation::ok();
}

Validation check_keyframe_poses(const dds_sequence_cdc_msg_KeyframePose& poses, const ValidationLimits& limits,
                                std::string_view field, const uint32_t* expected_robot) {
  if (auto v = check_sequence_max(poses, limits.max_poses, field); !v) {
    return v;
  }
  for (uint32_t i = 0; i < poses._length; ++i) {
    const cdc_msg_KeyframePose& kp = poses._buffer[i];
    const std::string f = std::string(field) + "[" + std::to_string(i) + "]";
    if (auto v = validate_robot_id(kp.robot_id, f + ".robot_id", limits); !v) {
      return v;
    }
    if (expected_robot != nullptr && kp.robot_id != *expected_robot) {
      return Validation::fail(f + ".robot_id: " + std::to_string(kp.robot_id) + " in a message about robot " +
                              std::to_string(*expected_robot));
    }
    if (auto v = validate_pose(kp.pose, f + ".pose", limits); !v) {
      return v;
    }
  }
  return Validation::ok();
}

// Runs checks in order and returns the first failure.
#define CDC_CHECK(expr)     \
  do {                      \
    Validation v_ = (expr); \
    if (!v_) {              \
      return v_;            \
    }                       \
  } while (false)

}  // namespace

Validation validate_robot_id(uint32_t id, std::string_view field, const ValidationLimits& limits) {
  if (id >= limits.robot_count || id > 254) {
    return Validation::fail(cat(field, ": unknown robot id " + std::to_string(id) + " (this swarm has robots 0.." +
                                           std::to_string(limits.robot_count - 1) + ")"));
  }
  return Validation::ok();
}

namespace {
// Both precisions of Pose.
template <class PoseMsg>
Validation check_pose(const PoseMsg& pose, std::string_view field, const ValidationLimits& limits) {
  CDC_CHECK(check_vec3(pose.position, cat(field, ".position")));
  const auto& q = pose.orientation;
  if (!finite(q.x) || !finite(q.y) || !finite(q.z) || !finite(q.w)) {
    return Validation::fail(cat(field, ".orientation: non-finite quaternion component"));
  }
  const double x = q.x, y = q.y, z = q.z, w = q.w;
  const double norm = std::sqrt(x * x + y * y + z * z + w * w);
  if (std::abs(norm - 1.0) > limits.quaternion_tolerance) {
    return Validation::fail(cat(field, ".orientation: not a unit quaternion (norm " + num(norm) + ", tolerance " +
                                           num(limits.quaternion_tolerance) + ")"));
  }
  return Validation::ok();
}
}  // namespace

Validation validate_pose(const cdc_msg_Pose& pose, std::string_view field, const ValidationLimits& limits) {
  return check_pose(pose, field, limits);
}

Validation validate_pose(const cdc_msg_PoseF& pose, std::string_view field, const ValidationLimits& limits) {
  return check_pose(pose, field, limits);
}

Validation validate_information(const cdc_msg_Information6& info, std::string_view field) {
  for (int i = 0; i < 36; ++i) {
    if (!finite(info[i])) {
      return Validation::fail(cat(field, "[" + std::to_string(i / 6) + "][" + std::to_string(i % 6) +
                                             "]: not a finite number (" + num(info[i]) + ")"));
    }
  }
  for (int r = 0; r < 6; ++r) {
    if (!(info[r * 6 + r] > 0.0)) {
      return Validation::fail(
          cat(field, ": diagonal entry " + std::to_string(r) + " is " + num(info[r * 6 + r]) + ", must be positive"));
    }
    for (int c = r + 1; c < 6; ++c) {
      const double a = info[r * 6 + c];
      const double b = info[c * 6 + r];
      if (std::abs(a - b) > 1e-6 * std::max({1.0, std::abs(a), std::abs(b)})) {
        return Validation::fail(cat(field, ": not symmetric at (" + std::to_string(r) + "," + std::to_string(c) + ")"));
      }
    }
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_LidarScan& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  if (m.stamp_ns < 0 || m.duration_ns < 0) {
    return Validation::fail("stamp_ns/duration_ns: negative time");
  }
  CDC_CHECK(check_sequence(m.points, m.point_count, limits.max_scan_points, "points"));
  const double duration_s = static_cast<double>(m.duration_ns) * 1e-9;
  for (uint32_t i = 0; i < m.points._length; ++i) {
    const cdc_msg_LidarPoint& p = m.points._buffer[i];
    if (!finite(p.x) || !finite(p.y) || !finite(p.z) || !finite(p.intensity) || !finite(p.time_offset)) {
      return Validation::fail("points[" + std::to_string(i) + "]: non-finite value (NaN/Inf)");
    }
    if (p.time_offset < 0.0f || p.time_offset > duration_s + 1e-6) {
      return Validation::fail("points[" + std::to_string(i) + "].time_offset: " + num(p.time_offset) +
                              " s outside the sweep [0, " + num(duration_s) + "] s");
    }
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_ImuBatch& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(check_sequence(m.samples, m.sample_count, limits.max_imu_samples, "samples"));
  for (uint32_t i = 0; i < m.samples._length; ++i) {
    const cdc_msg_ImuSample& s = m.samples._buffer[i];
    const std::string f = "samples[" + std::to_string(i) + "]";
    CDC_CHECK(check_vec3(s.linear_acceleration, f + ".linear_acceleration"));
    CDC_CHECK(check_vec3(s.angular_velocity, f + ".angular_velocity"));
    if (i > 0 && s.stamp_ns <= m.samples._buffer[i - 1].stamp_ns) {
      return Validation::fail(f + ".stamp_ns: not after the previous sample (out of order)");
    }
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_Odometry& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(validate_pose(m.T_odom_base, "T_odom_base", limits));
  if (m.world_valid) {
    CDC_CHECK(validate_pose(m.T_world_base, "T_world_base", limits));
  }
  CDC_CHECK(check_vec3(m.linear_velocity, "linear_velocity"));
  CDC_CHECK(check_vec3(m.angular_velocity, "angular_velocity"));
  return Validation::ok();
}

Validation validate(const cdc_msg_Keyframe& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(validate_pose(m.T_odom_keyframe, "T_odom_keyframe", limits));
  CDC_CHECK(validate_pose(m.T_prev_keyframe, "T_prev_keyframe", limits));
  CDC_CHECK(validate_information(m.information, "information"));
  CDC_CHECK(check_sequence(m.cloud, m.point_count, limits.max_cloud_points, "cloud"));
  return check_points(m.cloud._buffer, m.cloud._length, "cloud");
}

Validation validate(const cdc_msg_Descriptor& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  if (m.rings == 0 || m.sectors == 0) {
    return Validation::fail("rings/sectors: must be positive (got " + std::to_string(m.rings) + "x" +
                            std::to_string(m.sectors) + ")");
  }
  const uint32_t cells = uint32_t{m.rings} * uint32_t{m.sectors};
  if (cells > limits.max_descriptor_cells) {
    return Validation::fail("rings/sectors: " + std::to_string(cells) + " cells exceed the limit of " +
                            std::to_string(limits.max_descriptor_cells));
  }
  CDC_CHECK(check_sequence_max(m.packed_cells, static_cast<uint32_t>(compact::packed_bound(cells)), "packed_cells"));
  {
    thread_local std::vector<uint8_t> scratch;
    const std::string err = compact::inflate_bytes(m.packed_cells._buffer, m.packed_cells._length, cells, scratch);
    if (!err.empty()) return Validation::fail("packed_cells: " + err);
  }
  if (!(m.max_range > 0.0f) || !finite(m.max_range)) {
    return Validation::fail("max_range: must be a positive finite number (got " + num(m.max_range) + ")");
  }
  if (!(m.quant_scale > 0.0f) || !finite(m.quant_scale)) {
    return Validation::fail("quant_scale: must be a positive finite number (got " + num(m.quant_scale) + ")");
  }
  return validate_pose(m.pose_hint, "pose_hint", limits);
}

Validation validate(const cdc_msg_LoopClosure& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_a, "robot_a", limits));
  CDC_CHECK(validate_robot_id(m.robot_b, "robot_b", limits));
  CDC_CHECK(validate_robot_id(m.sender_robot_id, "sender_robot_id", limits));
  if (m.robot_a == m.robot_b && m.keyframe_a == m.keyframe_b) {
    return Validation::fail("keyframe_b: a loop closure from a keyframe to itself");
  }
  CDC_CHECK(check_enum(m.status, 2, "status"));
  CDC_CHECK(validate_pose(m.T_a_b, "T_a_b", limits));
  CDC_CHECK(validate_information(m.information, "information"));
  if (!finite(m.fitness) || m.fitness < 0.0f) {
    return Validation::fail("fitness: must be a finite non-negative number (got " + num(m.fitness) + ")");
  }
  return Validation::ok();
}

namespace {
// A request between two robots, or its answer, names both ends.
template <typename M>
Validation validate_ends(const M& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.requester_robot_id, "requester_robot_id", limits));
  return validate_robot_id(m.owner_robot_id, "owner_robot_id", limits);
}
}  // namespace

Validation validate(const cdc_msg_CloudRequest& m, const ValidationLimits& limits) { return validate_ends(m, limits); }

Validation validate(const cdc_msg_DescriptorSync& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_ends(m, limits));
  if (m.first_keyframe_id > m.last_keyframe_id) {
    return Validation::fail("last_keyframe_id: " + std::to_string(m.last_keyframe_id) +
                            " is before first_keyframe_id " + std::to_string(m.first_keyframe_id));
  }
  return Validation::ok();
}

namespace {
// A packed cloud (compact::pack_points) of `count` points: within the limits, no larger than the
// codec can make it, and decodable.
template <class Seq>
Validation check_packed_points(uint32_t count, const Seq& packed, float resolution_m, const ValidationLimits& limits) {
  if (count > limits.max_cloud_points) {
    return Validation::fail("point_count: " + std::to_string(count) + " points exceed the limit of " +
                            std::to_string(limits.max_cloud_points));
  }
  CDC_CHECK(
      check_sequence_max(packed, static_cast<uint32_t>(compact::packed_bound(6 * size_t{count})), "packed_points"));
  thread_local std::vector<Eigen::Vector3f> scratch;
  const std::string err = compact::unpack_points(packed._buffer, packed._length, count, resolution_m, scratch);
  if (!err.empty()) return Validation::fail("packed_points: " + err);
  return Validation::ok();
}
}  // namespace

Validation validate(const cdc_msg_CloudReply& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_ends(m, limits));
  if (!m.found && (m.point_count != 0 || m.packed_points._length != 0)) {
    return Validation::fail("packed_points: points in a reply that says the keyframe was not found");
  }
  return check_packed_points(m.point_count, m.packed_points, m.resolution_m, limits);
}

Validation validate(const cdc_msg_KeyframeCloud& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  return check_packed_points(m.point_count, m.packed_points, m.resolution_m, limits);
}

Validation validate(const cdc_msg_OptimizedPoses& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(check_node_id(m.sender_robot_id, "sender_robot_id", limits));
  CDC_CHECK(check_enum(m.source, 3, "source"));
  CDC_CHECK(validate_pose(m.T_world_robot, "T_world_robot", limits));
  return check_keyframe_poses(m.poses, limits, "poses", &m.robot_id);
}

Validation validate(const cdc_msg_SeparatorPoses& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(validate_robot_id(m.target_robot_id, "target_robot_id", limits));
  CDC_CHECK(check_sequence_max(m.poses, limits.max_poses, "poses"));
  for (uint32_t i = 0; i < m.poses._length; ++i) {
    CDC_CHECK(validate_pose(m.poses._buffer[i].pose, "poses[" + std::to_string(i) + "].pose", limits));
  }
  CDC_CHECK(check_sequence_max(m.loops, limits.max_poses, "loops"));
  for (uint32_t i = 0; i < m.loops._length; ++i) {
    const cdc_msg_LoopClosure& l = m.loops._buffer[i];
    const std::string field = "loops[" + std::to_string(i) + "]";
    if (const Validation v = validate(l, limits); !v) {
      return Validation::fail(field + "." + v.reason());
    }
    if (l.robot_a == l.robot_b || (l.robot_a != m.robot_id && l.robot_b != m.robot_id)) {
      return Validation::fail(field + ": not an inter-robot loop of the sender, robot " + std::to_string(m.robot_id) +
                              " (robots " + std::to_string(l.robot_a) + " and " + std::to_string(l.robot_b) + ")");
    }
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_WorldTransform& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(check_enum(m.source, 3, "source"));
  return validate_pose(m.T_world_robot, "T_world_robot", limits);
}

Validation validate(const cdc_msg_KeyframeSequence& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  if (m.newest_keyframe_id < -1 || m.newest_keyframe_id > int64_t{std::numeric_limits<uint32_t>::max()}) {
    return Validation::fail("newest_keyframe_id: " + std::to_string(m.newest_keyframe_id) +
                            " is neither -1 nor a keyframe id");
  }
  return validate_pose(m.T_odom_keyframe, "T_odom_keyframe", limits);
}

Validation validate(const cdc_msg_ModeState& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(check_enum(m.mode, 2, "mode"));
  CDC_CHECK(check_enum(m.reason, 4, "reason"));
  return check_finite(m.distance_to_central, "distance_to_central");
}

Validation validate(const cdc_msg_RobotStatus& m, const ValidationLimits& limits) {
  CDC_CHECK(check_node_id(m.robot_id, "robot_id", limits));
  CDC_CHECK(check_enum(m.mode, 2, "mode"));
  if (m.last_keyframe_id < -1) {
    return Validation::fail("last_keyframe_id: " + std::to_string(m.last_keyframe_id) + " is below -1");
  }
  if (m.world_valid) {
    CDC_CHECK(validate_pose(m.T_world_base, "T_world_base", limits));
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_Acknowledgement& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  if (m.highest_contiguous_keyframe < -1 || m.highest_contiguous_loop_seq < -1) {
    return Validation::fail("highest_contiguous_*: below -1");
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_GroundTruth& m, const ValidationLimits& limits) {
  CDC_CHECK(validate_robot_id(m.robot_id, "robot_id", limits));
  return validate_pose(m.T_world_base, "T_world_base", limits);
}

Validation validate(const cdc_msg_RadioState& m, const ValidationLimits& limits) {
  CDC_CHECK(check_sequence_max(m.links, 255u * 255u, "links"));
  for (uint32_t i = 0; i < m.links._length; ++i) {
    const cdc_msg_RadioLink& l = m.links._buffer[i];
    const std::string f = "links[" + std::to_string(i) + "]";
    CDC_CHECK(check_node_id(l.node_a, f + ".node_a", limits));
    CDC_CHECK(check_node_id(l.node_b, f + ".node_b", limits));
    if (!finite(l.distance) || l.distance < 0.0f) {
      return Validation::fail(f + ".distance: must be finite and non-negative (got " + num(l.distance) + ")");
    }
    if (!(l.loss_probability >= 0.0f && l.loss_probability <= 1.0f)) {
      return Validation::fail(f + ".loss_probability: " + num(l.loss_probability) + " outside [0, 1]");
    }
  }
  return Validation::ok();
}

Validation validate(const cdc_msg_ConsumerProgress& m, const ValidationLimits& limits) {
  return validate_robot_id(m.robot_id, "robot_id", limits);
}

bool RejectionCounter::record(std::string_view topic, const Validation& v) {
  if (v) {
    return false;
  }
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = counts_.find(topic);
  if (it == counts_.end()) {
    it = counts_.emplace(std::string(topic), 0).first;
  }
  ++it->second;
  ++total_;
  last_reason_ = std::string(topic) + ": " + v.reason();
  return true;
}

uint64_t RejectionCounter::total() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return total_;
}

uint64_t RejectionCounter::count(std::string_view topic) const {
  std::lock_guard<std::mutex> lock(mutex_);
  auto it = counts_.find(topic);
  return it == counts_.end() ? 0 : it->second;
}

std::map<std::string, uint64_t> RejectionCounter::by_topic() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return {counts_.begin(), counts_.end()};
}

std::string RejectionCounter::last_reason() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return last_reason_;
}

}  // namespace cdc::dds
