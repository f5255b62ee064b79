#include "frontend_node.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/runtime/stats.hpp"

#include <spdlog/spdlog.h>

#include <cmath>
#include <optional>

namespace cdc::frontend {

// Counters as --stats-out names them.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(FrontendStats, scans, keyframes, registration_failures, corrections,
                                   corrections_levelled, imu_samples, registration_rejected, imu_predictions,
                                   imu_predictions_rejected, imu_window_restarts, recovery_attempts, recoveries,
                                   recoveries_global, level_deg, max_level_deg)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(FrontendNodeCounters, odometry, keyframes, corrections_for_unknown_keyframes,
                                   imu_gaps, imu_late)

namespace {

namespace topics = dds::topics;

dds::ValidationLimits limits(const FrontendNodeOptions& o) {
  dds::ValidationLimits l = runtime::swarm_limits(o.robots);
  l.max_scan_points = o.max_scan_points;
  return l;
}

}  // namespace

// Sweeps, IMU and lock-step progress may live on a domain of their own (the simulator's), so that
// they never cross the emulated radio; by default they share the SLAM domain.
FrontendNode::FrontendNode(const runtime::ServiceOptions& common, const FrontendNodeOptions& o)
    : o_(o),
      service_(runtime::Domains::kWithSensors, common, limits(o),
               dds::local_domain_options(o.sensor_domain, o.sensor_dds_config, common.radio())),
      scans_(service_, service_.secondary(), topics::kLidar, dds::qos::sensor_stream(16, true)),
      imu_(service_, service_.secondary(), topics::kImu, dds::qos::sensor_stream(64, true)),
      corrections_(service_, service_.radio(), topics::kCorrection,
                   dds::qos::event_stream(64).partitions(dds::partitions::own_reader(common.robot))),
      // Where the back-end's keyframe sequence stands (transient-local: what it last wrote comes at once).
      sequence_(service_, service_.radio(), topics::kKeyframeSequence,
                dds::qos::keyed_state().partitions(dds::partitions::own_reader(common.robot))),
      w_odom_(service_.radio(), topics::kOdometry,
              dds::qos::sensor_stream(16, true).partitions({dds::partitions::robot(common.robot)})),
      w_kf_(service_.radio(), topics::kKeyframe,
            dds::qos::event_stream(4096).partitions({dds::partitions::robot(common.robot)})),
      w_progress_(service_.secondary(), topics::kProgress, dds::qos::keyed_state()),
      core_(o.core) {
  const uint32_t me = common.robot;
  imu_.filter([this, me](const cdc_msg_ImuBatch& m) { return m.robot_id == me && o_.use_imu; })
      .on([this](const cdc_msg_ImuBatch& m) { on_imu(m); });
  corrections_.filter([this, me](const cdc_msg_OptimizedPoses& m) { return m.robot_id == me && o_.take_corrections; })
      .on([this](const cdc_msg_OptimizedPoses& m) { on_correction(m); });
  sequence_.filter([me](const cdc_msg_KeyframeSequence& m) { return m.robot_id == me; })
      .on([this](const cdc_msg_KeyframeSequence& m) { on_sequence(m); });
  scans_.filter([me](const cdc_msg_LidarScan& m) { return m.robot_id == me; })
      .check([this](const cdc_msg_LidarScan& m) { return check_scan(m); })
      .on([this](const cdc_msg_LidarScan& m) { on_scan(m); });
  spdlog::info("front-end of robot {} up: {}deskewing, IMU {}, keyframes every {} m / {} deg, domain {}", me,
               o.core.deskew ? "" : "no ", o.use_imu ? "on" : "off", o.core.keyframe_distance_m,
               o.core.keyframe_angle_rad * 180 / M_PI, common.domain_id());
  if (service_.split()) spdlog::info("sensors and lock-step progress on domain {}", o.sensor_domain);
}

void FrontendNode::spin() {
  while (service_.wait(pending_.empty() ? std::chrono::milliseconds(200) : std::chrono::milliseconds(5))) {
    imu_.poll(64);  // IMU first: a sweep needs the samples up to its end
    corrections_.poll(16);
    sequence_.poll(4);
    scans_.poll(4);
    process_ready_scans();
  }
}

void FrontendNode::on_imu(const cdc_msg_ImuBatch& m) {
  for (uint32_t i = 0; i < m.samples._length; ++i) {
    const cdc_msg_ImuSample& s = m.samples._buffer[i];
    if (s.stamp_ns <= last_imu_stamp_) {
      service_.boundary().refuse(
          topics::kImu, dds::Validation::fail("samples[" + std::to_string(i) +
                                              "].stamp_ns: not after the last sample received (out of order)"));
      continue;
    }
    if (last_imu_stamp_ >= 0 && static_cast<double>(s.stamp_ns - last_imu_stamp_) * 1e-9 > o_.imu_gap_s) {
      ++counters_.imu_gaps;
      spdlog::warn("IMU gap of {:.3f} s before {} ns: bridged with constant velocity",
                   static_cast<double>(s.stamp_ns - last_imu_stamp_) * 1e-9, s.stamp_ns);
      core_.clear_imu();
    }
    last_imu_stamp_ = s.stamp_ns;
    core_.add_imu({s.stamp_ns, dds::to_eigen(s.angular_velocity), dds::to_eigen(s.linear_acceleration)});
  }
}

void FrontendNode::on_correction(const cdc_msg_OptimizedPoses& m) {
  // The newest keyframe of the result that this front-end knows carries the correction.
  for (int64_t i = static_cast<int64_t>(m.poses._length) - 1; i >= 0; --i) {
    const cdc_msg_KeyframePose& kp = m.poses._buffer[i];
    const Eigen::Isometry3d T_world_keyframe = dds::to_eigen(kp.pose), T_world_robot = dds::to_eigen(m.T_world_robot);
    if (core_.set_correction(kp.keyframe_id, T_world_keyframe, T_world_robot)) {
      const Eigen::Vector3d t = T_world_keyframe.translation(), w = T_world_robot.translation();
      spdlog::debug("correction: keyframe {} at ({:.3f}, {:.3f}, {:.3f}), T_world_robot at ({:.3f}, {:.3f}, {:.3f})",
                    kp.keyframe_id, t.x(), t.y(), t.z(), w.x(), w.y(), w.z());
      return;
    }
  }
  ++counters_.corrections_for_unknown_keyframes;
}

dds::Validation FrontendNode::check_scan(const cdc_msg_LidarScan& m) const {
  if (m.points._length == 0) return dds::Validation::fail("points: empty sweep");
  if (m.stamp_ns <= last_scan_stamp_) {
    return dds::Validation::fail("stamp_ns: " + std::to_string(m.stamp_ns) + " not after the previous sweep's " +
                                 std::to_string(last_scan_stamp_) + " (out of order)");
  }
  return dds::Validation::ok();
}

void FrontendNode::on_scan(const cdc_msg_LidarScan& m) {
  last_scan_stamp_ = m.stamp_ns;
  PendingScan& scan = pending_.emplace_back();
  scan.stamp_ns = m.stamp_ns;
  scan.end_ns = m.stamp_ns + static_cast<int64_t>(m.duration_ns);
  scan.seq = m.seq;
  scan.incarnation = m.incarnation;
  scan.received = std::chrono::steady_clock::now();
  scan.points.reserve(m.points._length);
  for (uint32_t i = 0; i < m.points._length; ++i) {
    const cdc_msg_LidarPoint& p = m.points._buffer[i];
    scan.points.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
  }
}

void FrontendNode::on_sequence(const cdc_msg_KeyframeSequence& m) { backend_sequence_ = m; }

// Keyframe ids name one keyframe of the robot's sequence for every consumer (idl/README.md): before
// its first sweep the front-end learns from its back-end where the sequence stands and continues it
// (a restart), or starts a new one under its sweeps' incarnation when the back-end holds none or does
// not answer within sequence_wait.
bool FrontendNode::sequence_decided() {
  if (sequence_incarnation_) return true;
  const bool waited = std::chrono::steady_clock::now() - started_ >= o_.sequence_wait;
  if (!backend_sequence_ && !waited) return false;
  if (backend_sequence_ && backend_sequence_->newest_keyframe_id >= 0) {
    const cdc_msg_KeyframeSequence& b = *backend_sequence_;
    core_.continue_sequence(static_cast<uint32_t>(b.newest_keyframe_id), dds::to_eigen(b.T_odom_keyframe));
    sequence_incarnation_ = b.incarnation;
    spdlog::info("continuing robot {}'s keyframe sequence of incarnation {} after keyframe {}",
                 service_.options().robot, b.incarnation, b.newest_keyframe_id);
    return true;
  }
  sequence_incarnation_ = pending_.front().incarnation;
  spdlog::info("a new keyframe sequence of incarnation {} ({})", *sequence_incarnation_,
               backend_sequence_ ? "the back-end holds no keyframe" : "no back-end answered");
  return true;
}

// A sweep and the IMU samples up to its end travel on different topics and may arrive in either
// order: a sweep waits (at most imu_wait) until the IMU has reached its end.
void FrontendNode::process_ready_scans() {
  while (!pending_.empty() && sequence_decided()) {
    const PendingScan& scan = pending_.front();
    const bool imu_covers = !o_.use_imu || last_imu_stamp_ >= scan.end_ns - static_cast<int64_t>(o_.imu_gap_s * 1e9);
    if (!imu_covers && std::chrono::steady_clock::now() - scan.received < o_.imu_wait) break;
    if (!imu_covers) ++counters_.imu_late;
    incarnation_ = scan.incarnation;
    const FrontendStats before = core_.stats();
    const ScanOut out = core_.process(scan.stamp_ns, scan.points);
    log_registration_failure(scan, before, out);
    publish(scan, out);
    pending_.pop_front();
  }
}

// Counted in the stats; logged the first ten times, then every hundredth.
void FrontendNode::log_registration_failure(const PendingScan& scan, const FrontendStats& before,
                                            const ScanOut& out) const {
  const uint64_t failures = core_.stats().registration_failures;
  if (failures <= before.registration_failures || (failures > 10 && failures % 100 != 0)) return;
  spdlog::warn("sweep {}: registration {} ({} correspondences, rmse {:.3f} m); the prediction stands in ({} so far)",
               scan.seq,
               core_.stats().registration_rejected > before.registration_rejected
                   ? "rejected: it landed implausibly far from the prediction"
                   : "did not converge",
               out.registration.correspondences, out.registration.rmse, failures);
}

void FrontendNode::publish(const PendingScan& scan, const ScanOut& out) {
  cdc_msg_Odometry od{};
  od.robot_id = service_.options().robot;
  od.incarnation = incarnation_;
  od.scan_seq = scan.seq;
  od.stamp_ns = scan.stamp_ns;
  od.T_odom_base = dds::to_msg(out.T_odom_base);
  od.world_valid = out.T_world_base.has_value();
  od.T_world_base = dds::to_msg(out.T_world_base.value_or(Eigen::Isometry3d::Identity()));
  od.linear_velocity = dds::to_msg(out.linear_velocity);
  od.angular_velocity = dds::to_msg(out.angular_velocity);
  w_odom_.write(od);
  ++counters_.odometry;
  if (!o_.trajectory_out.empty()) trajectory_.push_back({scan.stamp_ns, out.T_odom_base});
  if (out.keyframe) publish_keyframe(*out.keyframe);
  w_progress_.write(cdc_msg_ConsumerProgress{service_.options().robot, incarnation_, scan.seq});
}

void FrontendNode::publish_keyframe(const KeyframeOut& k) {
  cloud_.clear();
  for (const auto& p : k.cloud) cloud_.push_back(cdc_msg_PointXYZI{p.x(), p.y(), p.z(), 0.0f});
  cdc_msg_Keyframe kf{};
  kf.robot_id = service_.options().robot;
  kf.keyframe_id = k.id;
  kf.incarnation = *sequence_incarnation_;
  kf.stamp_ns = k.stamp_ns;
  dds::keyframe_body_to_msg(k.T_odom_keyframe, k.T_prev, k.information, cloud_, kf);
  w_kf_.write(kf);
  ++counters_.keyframes;
}

nlohmann::json FrontendNode::stats() const {
  nlohmann::json j = core_.stats();
  j.update(nlohmann::json(counters_));
  j["robot"] = service_.options().robot;
  return j;
}

void FrontendNode::finish() const {
  if (!o_.trajectory_out.empty()) geometry::write_tum(o_.trajectory_out, trajectory_);
  runtime::write_stats(service_, stats());
  spdlog::info("stopped after {} sweeps, {} keyframes, {} rejected samples", counters_.odometry, counters_.keyframes,
               service_.boundary().rejected().total());
}

}  // namespace cdc::frontend
