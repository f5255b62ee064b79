#include "frontend_node.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <deque>
#include <fstream>
#include <optional>

namespace cdc::frontend {
namespace {
namespace topics = dds::topics;
}  // namespace

int run_frontend(const FrontendNodeOptions& o) {
  const uint32_t me = o.robot;
  dds::ParticipantOptions po;
  po.domain_id = o.domain;
  po.config = o.dds_config;
  dds::Participant participant(po);
  // Sensors and lock-step progress may live on a domain of their own (the simulator's), so that
  // they never cross the emulated radio; by default they share the SLAM domain.
  std::optional<dds::Participant> sensor_participant;
  if (o.sensor_domain >= 0 && static_cast<uint32_t>(o.sensor_domain) != o.domain) {
    dds::ParticipantOptions so = po;
    so.domain_id = static_cast<uint32_t>(o.sensor_domain);
    if (!o.sensor_dds_config.empty()) so.config = o.sensor_dds_config;
    sensor_participant.emplace(so);
  }
  const dds::Participant& sensors = sensor_participant ? *sensor_participant : participant;
  dds::Topic<cdc_msg_LidarScan> t_scan(sensors, topics::kLidar);
  dds::Topic<cdc_msg_ImuBatch> t_imu(sensors, topics::kImu);
  dds::Topic<cdc_msg_ConsumerProgress> t_progress(sensors, topics::kProgress);
  dds::Topic<cdc_msg_OptimizedPoses> t_corr(participant, topics::kCorrection);
  dds::Topic<cdc_msg_Odometry> t_odom(participant, topics::kOdometry);
  dds::Topic<cdc_msg_Keyframe> t_kf(participant, topics::kKeyframe);
  dds::Reader<cdc_msg_LidarScan> r_scan(sensors, t_scan, dds::qos::sensor_stream(16, true));
  dds::Reader<cdc_msg_ImuBatch> r_imu(sensors, t_imu, dds::qos::sensor_stream(64, true));
  dds::Reader<cdc_msg_OptimizedPoses> r_corr(participant, t_corr, dds::qos::event_stream(64).partitions(dds::partitions::own_reader(me)));
  dds::Writer<cdc_msg_Odometry> w_odom(participant, t_odom, dds::qos::sensor_stream(16, true).partitions({dds::partitions::robot(me)}));
  dds::Writer<cdc_msg_Keyframe> w_kf(participant, t_kf, dds::qos::event_stream(4096).partitions({dds::partitions::robot(me)}));
  dds::Writer<cdc_msg_ConsumerProgress> w_progress(sensors, t_progress, dds::qos::keyed_state());
  // The waitset belongs to the sensors' participant; corrections are taken on every wake-up
  // (at least every 200 ms) when they arrive on the other one.
  dds::GuardCondition stop(sensors);
  dds::ShutdownSignal::add_guard(&stop);
  dds::ReadCondition rc_scan(r_scan.handle()), rc_imu(r_imu.handle());
  dds::WaitSet ws(sensors);
  ws.attach(stop.handle(), 0);
  ws.attach(rc_scan.handle(), 1);
  ws.attach(rc_imu.handle(), 2);
  std::optional<dds::ReadCondition> rc_corr;
  if (!sensor_participant) {
    rc_corr.emplace(r_corr.handle());
    ws.attach(rc_corr->handle(), 3);
  }

  dds::ValidationLimits limits;
  limits.robot_count = o.robots;
  limits.max_scan_points = o.max_scan_points;
  dds::RejectionCounter rejected;
  FrontendCore core(o.core);
  int64_t last_scan_stamp = -1, last_imu_stamp = -1;
  uint64_t imu_gaps = 0, odometry_sent = 0, keyframes_sent = 0, corrections_unknown = 0;
  uint32_t incarnation = 0;
  geometry::Trajectory trajectory;
  std::vector<cdc_msg_PointXYZI> cloud;
  spdlog::info("front-end of robot {} up: {}deskewing, IMU {}, keyframes every {} m / {} deg, domain {}", me,
               o.core.deskew ? "" : "no ", o.use_imu ? "on" : "off", o.core.keyframe_distance_m,
               o.core.keyframe_angle_rad * 180 / M_PI, o.domain);
  if (sensor_participant) spdlog::info("sensors and lock-step progress on domain {}", o.sensor_domain);
  auto reject = [&](const char* topic, dds::Validation v) {
    if (rejected.record(topic, v)) {
      spdlog::warn("rejected {}: {}", topic, rejected.last_reason());
      return true;
    }
    return false;
  };

  struct PendingScan {
    int64_t stamp_ns = 0, end_ns = 0;
    uint64_t seq = 0;
    uint32_t incarnation = 0;
    std::chrono::steady_clock::time_point received;
    std::vector<ScanPoint> points;
  };
  std::deque<PendingScan> pending;
  uint64_t imu_late = 0;  // sweeps processed before the IMU reached their end (waited imu_wait)
  while (!dds::ShutdownSignal::requested()) {
    ws.wait(pending.empty() ? std::chrono::milliseconds(200) : std::chrono::milliseconds(5));
    // IMU first: a sweep needs the samples up to its end.
    r_imu.take(64).for_each_valid([&](const cdc_msg_ImuBatch& m, const dds_sample_info_t&) {
      if (m.robot_id != me || !o.use_imu) return;
      if (reject(topics::kImu, dds::validate(m, limits))) return;
      for (uint32_t i = 0; i < m.samples._length; ++i) {
        const cdc_msg_ImuSample& s = m.samples._buffer[i];
        if (s.stamp_ns <= last_imu_stamp) {
          reject(topics::kImu, dds::Validation::fail("samples[" + std::to_string(i) + "].stamp_ns: not after the last sample received (out of order)"));
          continue;
        }
        if (last_imu_stamp >= 0 && static_cast<double>(s.stamp_ns - last_imu_stamp) * 1e-9 > o.imu_gap_s) {
          ++imu_gaps;
          spdlog::warn("IMU gap of {:.3f} s before {} ns: bridged with constant velocity",
                       static_cast<double>(s.stamp_ns - last_imu_stamp) * 1e-9, s.stamp_ns);
          core.clear_imu();
        }
        last_imu_stamp = s.stamp_ns;
        core.add_imu({s.stamp_ns, dds::to_eigen(s.angular_velocity), dds::to_eigen(s.linear_acceleration)});
      }
    });
    r_corr.take(16).for_each_valid([&](const cdc_msg_OptimizedPoses& m, const dds_sample_info_t&) {
      if (m.robot_id != me || !o.take_corrections) return;
      if (reject(topics::kCorrection, dds::validate(m, limits))) return;
      // The newest keyframe of the result that this front-end knows carries the correction.
      for (int64_t i = static_cast<int64_t>(m.poses._length) - 1; i >= 0; --i) {
        const cdc_msg_KeyframePose& kp = m.poses._buffer[i];
        const Eigen::Isometry3d T_world_keyframe = dds::to_eigen(kp.pose), T_world_robot = dds::to_eigen(m.T_world_robot);
        if (core.set_correction(kp.keyframe_id, T_world_keyframe, T_world_robot)) {
          const Eigen::Vector3d t = T_world_keyframe.translation(), w = T_world_robot.translation();
          spdlog::debug("correction: keyframe {} at ({:.3f}, {:.3f}, {:.3f}), T_world_robot at ({:.3f}, {:.3f}, {:.3f})",
                        kp.keyframe_id, t.x(), t.y(), t.z(), w.x(), w.y(), w.z());
          return;
        }
      }
      ++corrections_unknown;
    });
    r_scan.take(4).for_each_valid([&](const cdc_msg_LidarScan& m, const dds_sample_info_t&) {
      if (m.robot_id != me) return;
      dds::Validation v = dds::validate(m, limits);
      if (v && m.points._length == 0) v = dds::Validation::fail("points: empty sweep");
      if (v && m.stamp_ns <= last_scan_stamp) {
        v = dds::Validation::fail("stamp_ns: " + std::to_string(m.stamp_ns) + " not after the previous sweep's " +
                                  std::to_string(last_scan_stamp) + " (out of order)");
      }
      if (reject(topics::kLidar, v)) return;
      last_scan_stamp = m.stamp_ns;
      PendingScan& scan = pending.emplace_back();
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
    });
    // A sweep and the IMU samples up to its end travel on different topics and may arrive in either
    // order: a sweep waits (at most imu_wait) until the IMU has reached its end.
    while (!pending.empty()) {
      const PendingScan& scan = pending.front();
      const bool imu_covers = !o.use_imu || last_imu_stamp >= scan.end_ns - static_cast<int64_t>(o.imu_gap_s * 1e9);
      if (!imu_covers && std::chrono::steady_clock::now() - scan.received < o.imu_wait) break;
      if (!imu_covers) ++imu_late;
      incarnation = scan.incarnation;
      const FrontendStats before = core.stats();
      const ScanOut out = core.process(scan.stamp_ns, scan.points);
      const uint64_t failures = core.stats().registration_failures;
      if (failures > before.registration_failures && (failures <= 10 || failures % 100 == 0)) {
        // Counted in the stats; logged the first ten times, then every hundredth.
        spdlog::warn("sweep {}: registration {} ({} correspondences, rmse {:.3f} m); the prediction stands in "
                     "({} so far)", scan.seq,
                     core.stats().registration_rejected > before.registration_rejected
                         ? "rejected: it landed implausibly far from the prediction"
                         : "did not converge",
                     out.registration.correspondences, out.registration.rmse, failures);
      }
      cdc_msg_Odometry od{};
      od.robot_id = me;
      od.incarnation = incarnation;
      od.scan_seq = scan.seq;
      od.stamp_ns = scan.stamp_ns;
      od.T_odom_base = dds::to_msg(out.T_odom_base);
      od.world_valid = out.T_world_base.has_value();
      od.T_world_base = dds::to_msg(out.T_world_base.value_or(Eigen::Isometry3d::Identity()));
      od.linear_velocity = dds::to_msg(out.linear_velocity);
      od.angular_velocity = dds::to_msg(out.angular_velocity);
      w_odom.write(od);
      ++odometry_sent;
      if (!o.trajectory_out.empty()) trajectory.push_back({scan.stamp_ns, out.T_odom_base});
      if (out.keyframe) {
        const KeyframeOut& k = *out.keyframe;
        cloud.clear();
        for (const auto& p : k.cloud) cloud.push_back(cdc_msg_PointXYZI{p.x(), p.y(), p.z(), 0.0f});
        cdc_msg_Keyframe kf{};
        kf.robot_id = me;
        kf.keyframe_id = k.id;
        kf.incarnation = incarnation;
        kf.stamp_ns = k.stamp_ns;
        kf.T_odom_keyframe = dds::to_msg(k.T_odom_keyframe);
        kf.T_prev_keyframe = dds::to_msg(k.T_prev);
        dds::information_to_msg(k.information, kf.information);
        kf.point_count = static_cast<uint32_t>(cloud.size());
        dds::borrow(kf.cloud, cloud);
        w_kf.write(kf);
        ++keyframes_sent;
      }
      w_progress.write(cdc_msg_ConsumerProgress{me, incarnation, scan.seq});
      pending.pop_front();
    }
  }
  dds::ShutdownSignal::remove_guard(&stop);
  if (!o.trajectory_out.empty()) geometry::write_tum(o.trajectory_out, trajectory);
  if (!o.stats_out.empty()) {
    const FrontendStats& s = core.stats();
    nlohmann::json j{{"robot", me},
                     {"scans", s.scans},
                     {"odometry", odometry_sent},
                     {"keyframes", keyframes_sent},
                     {"registration_failures", s.registration_failures},
                     {"registration_rejected", s.registration_rejected},
                     {"recovery_attempts", s.recovery_attempts},
                     {"recoveries", s.recoveries},
                     {"recoveries_global", s.recoveries_global},
                     {"imu_predictions", s.imu_predictions},
                     {"imu_predictions_rejected", s.imu_predictions_rejected},
                     {"imu_window_restarts", s.imu_window_restarts},
                     {"level_deg", s.level_deg},
                     {"max_level_deg", s.max_level_deg},
                     {"corrections", s.corrections},
                     {"corrections_levelled", s.corrections_levelled},
                     {"corrections_for_unknown_keyframes", corrections_unknown},
                     {"imu_samples", s.imu_samples},
                     {"imu_gaps", imu_gaps},
                     {"imu_late", imu_late},
                     {"rejected", rejected.by_topic()},
                     {"rejected_samples", rejected.total()}};
    j["topics"] = dds::topic_traffic_json();
    std::ofstream(o.stats_out) << j.dump(2) << '\n';
  }
  spdlog::info("stopped after {} sweeps, {} keyframes, {} rejected samples", odometry_sent, keyframes_sent, rejected.total());
  return 0;
}

}  // namespace cdc::frontend
