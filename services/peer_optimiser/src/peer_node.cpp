#include "peer_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/liveliness.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/runtime/logging.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <optional>

namespace cdc::peer {
namespace {

using Clock = std::chrono::steady_clock;
namespace topics = dds::topics;

struct StoredKeyframe {
  cdc_msg_Keyframe msg{};                  // sequences detached
  std::vector<cdc_msg_PointXYZI> cloud;
};

cdc_msg_SwitchReason to_msg(SwitchReason r) {
  switch (r) {
    case SwitchReason::kStartup: return cdc_msg_REASON_STARTUP;
    case SwitchReason::kLivelinessLost: return cdc_msg_REASON_LIVELINESS_LOST;
    case SwitchReason::kOutOfRange: return cdc_msg_REASON_OUT_OF_RANGE;
    case SwitchReason::kBackInRange: return cdc_msg_REASON_BACK_IN_RANGE;
  }
  return cdc_msg_REASON_STARTUP;
}

// The back-end mode as the mode and status messages carry it, and back.
cdc_msg_BackendMode to_msg(Mode m) { return m == Mode::kCentralized ? cdc_msg_MODE_CENTRALIZED : cdc_msg_MODE_DISTRIBUTED; }
Mode from_msg(cdc_msg_BackendMode m) { return m == cdc_msg_MODE_CENTRALIZED ? Mode::kCentralized : Mode::kDistributed; }

}  // namespace

PeerNodeOptions load_options(const std::string& path) {
  PeerNodeOptions o;
  config::Reader r(path);
  auto positive_d = [](const double& v) { return v > 0; };
  auto positive_i = [](const int& v) { return v > 0; };
  int robots = static_cast<int>(o.core.robot_count);
  r.get<int>("robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.core.robot_count = static_cast<uint32_t>(robots);
  r.get<double>("range_m", o.core.rtdos.range_m, positive_d, "> 0");
  r.get<double>("hysteresis_m", o.core.rtdos.hysteresis_m, [](const double& v) { return v >= 0; }, ">= 0");
  int dwell = 3000, mask = 2000, round = 200, grace = 1500, resend = 500, refresh = 2000;
  r.get<int>("dwell_ms", dwell, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>("mask_ms", mask, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>("round_period_ms", round, positive_i, "> 0");
  r.get<int>("resend_grace_ms", grace, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>("resend_period_ms", resend, positive_i, "> 0");
  r.get<int>("separator_refresh_ms", refresh, positive_i, "> 0");
  o.core.rtdos.dwell = std::chrono::milliseconds(dwell);
  o.core.rtdos.mask = std::chrono::milliseconds(mask);
  o.core.round_period = std::chrono::milliseconds(round);
  o.core.resend_grace = std::chrono::milliseconds(grace);
  o.core.resend_period = std::chrono::milliseconds(resend);
  o.core.separator_refresh = std::chrono::milliseconds(refresh);
  r.get<double>("peer_range_m", o.core.peer_range_m, positive_d, "> 0");
  r.get<int>("distributed_iterations", o.core.distributed_iterations, positive_i, "> 0");
  r.get<double>("distributed_relaxation", o.core.relaxation, [](const double& v) { return v > 0 && v <= 1; }, "in (0, 1]");
  r.get<bool>("share_loop_information", o.core.share_loop_information);
  const auto non_negative_d = [](const double& v) { return v >= 0; };
  r.get<double>("separator_min_change_m", o.core.separator_min_change_m, non_negative_d, ">= 0");
  double sep_deg = o.core.separator_min_change_rad * 180.0 / M_PI;
  r.get<double>("separator_min_change_deg", sep_deg, non_negative_d, ">= 0");
  o.core.separator_min_change_rad = sep_deg * M_PI / 180.0;
  r.get<double>("fusion.pos_max_m", o.core.fusion.pos_max, positive_d, "> 0");
  double rot_deg = o.core.fusion.rot_max * 180.0 / M_PI;
  r.get<double>("fusion.rot_max_deg", rot_deg, positive_d, "> 0");
  o.core.fusion.rot_max = rot_deg * M_PI / 180.0;
  int central_id = static_cast<int>(o.central_id);
  r.get<int>("central_id", central_id, [](const int& v) { return v >= 0 && v <= 254; }, "0..254");
  o.central_id = static_cast<uint32_t>(central_id);
  r.get<int>("tick_ms", o.tick_ms, positive_i, "> 0");
  r.get<int>("status_period_ms", o.status_period_ms, positive_i, "> 0");
  r.get<int>("radio_status_period_ms", o.radio_status_period_ms, positive_i, "> 0");
  r.get<std::string>("log_level", o.log_level);
  if (o.core.rtdos.hysteresis_m >= o.core.rtdos.range_m) {
    r.error("hysteresis_m must be smaller than range_m");
  }
  r.finish();
  return o;
}

int run_peer(const PeerNodeOptions& o) {
  const uint32_t me = o.core.robot;
  dds::ParticipantOptions po;
  po.domain_id = o.domain;
  po.config = o.dds_config;
  dds::RobotDomains domains(po, dds::local_domain_options(o.local_domain, o.local_dds_config, po), runtime::log_radio_switch);
  const dds::Participant& participant = domains.radio();
  const dds::Participant& local = domains.local();

  dds::Topic<cdc_msg_Keyframe> t_kf(participant, topics::kKeyframe);
  dds::Topic<cdc_msg_LoopClosure> t_loop(participant, topics::kLoopClosure);
  dds::Topic<cdc_msg_OptimizedPoses> t_central(participant, topics::kCentralOptimized);
  dds::Topic<cdc_msg_Acknowledgement> t_ack(participant, topics::kCentralAck);
  dds::Topic<cdc_msg_SeparatorPoses> t_sep(participant, topics::kSeparator);
  dds::Topic<cdc_msg_RobotStatus> t_status(participant, topics::kRobotStatus);
  dds::Topic<cdc_msg_ModeState> t_mode(participant, topics::kMode);
  dds::Topic<cdc_msg_OptimizedPoses> t_corr(participant, topics::kCorrection);
  dds::Topic<cdc_msg_WorldTransform> t_world(participant, topics::kWorldTransform);

  // The robot's own keyframes and loop closures, and its corrections, travel on its local domain
  // when it has one (see cdc/dds/robot_domains.hpp); the peer optimiser then forwards every keyframe
  // to the central over the radio, and takes loop closures from both domains (each counted once).
  std::optional<dds::Topic<cdc_msg_Keyframe>> t_kf_local;
  std::optional<dds::Topic<cdc_msg_LoopClosure>> t_loop_local;
  std::optional<dds::Topic<cdc_msg_OptimizedPoses>> t_corr_local;
  std::optional<dds::Reader<cdc_msg_LoopClosure>> r_loop_local;
  if (domains.split()) {
    t_kf_local.emplace(local, topics::kKeyframe);
    t_loop_local.emplace(local, topics::kLoopClosure);
    t_corr_local.emplace(local, topics::kCorrection);
    r_loop_local.emplace(local, *t_loop_local, dds::qos::event_stream(4096));
  }
  const dds::Topic<cdc_msg_Keyframe>& t_kf_own = t_kf_local ? *t_kf_local : t_kf;
  const dds::Topic<cdc_msg_OptimizedPoses>& t_corr_own = t_corr_local ? *t_corr_local : t_corr;
  dds::Reader<cdc_msg_Keyframe> r_kf(local, t_kf_own, dds::qos::event_stream(4096).partitions(dds::partitions::own_reader(me)));
  dds::Reader<cdc_msg_LoopClosure> r_loop(participant, t_loop,
                                          dds::qos::event_stream(4096).partitions(dds::partitions::own_reader(me)));
  // The central's results for this robot only (its partition); liveliness is watched below.
  dds::Reader<cdc_msg_OptimizedPoses> r_central(participant, t_central,
                                                dds::qos::monitored_reader().partitions({dds::partitions::robot(me)}));
  dds::Reader<cdc_msg_Acknowledgement> r_ack(participant, t_ack, dds::qos::keyed_state());
  dds::Reader<cdc_msg_SeparatorPoses> r_sep(participant, t_sep,
                                            dds::qos::event_stream(256).partitions(dds::partitions::own_reader(me)));
  dds::Reader<cdc_msg_RobotStatus> r_status(participant, t_status, dds::qos::keyed_state());
  dds::Writer<cdc_msg_ModeState> w_mode(participant, t_mode, dds::qos::keyed_state(8));
  dds::Writer<cdc_msg_OptimizedPoses> w_corr(local, t_corr_own, dds::qos::event_stream(64).partitions({dds::partitions::robot(me)}));
  // Separators go only to the peer they are for (each crosses only the link to it).
  dds::PerRobotWriters<cdc_msg_SeparatorPoses> w_sep(participant, t_sep, dds::qos::event_stream(256), o.core.robot_count, me);
  std::vector<uint32_t> sep_matches(o.core.robot_count, 0);  // per peer: its readers ever matched
  dds::Writer<cdc_msg_WorldTransform> w_world(participant, t_world, dds::qos::keyed_state());
  dds::Writer<cdc_msg_Keyframe> w_kf(participant, t_kf, dds::qos::event_stream(4096).partitions({dds::partitions::robot(me)}));
  // Own loops re-sent for the central: in the robot's partition, so that they do not cross to peers.
  dds::Writer<cdc_msg_LoopClosure> w_loop(participant, t_loop,
                                          dds::qos::event_stream(4096).partitions({dds::partitions::robot(me)}));
  dds::Writer<cdc_msg_RobotStatus> w_status(participant, t_status, dds::qos::keyed_state());
  dds::Topic<cdc_msg_RobotStatus> t_alive(participant, topics::kCentralAlive);
  dds::LivelinessMonitor central_liveliness(participant, t_alive.handle(), "central optimiser");

  dds::GuardCondition stop, liveliness_changed;  // in a waitset spanning both domains
  dds::ShutdownSignal::add_guard(&stop);
  central_liveliness.set_notify(&liveliness_changed);
  dds::ReadCondition rc_kf(r_kf.handle()), rc_loop(r_loop.handle()), rc_central(r_central.handle()),
      rc_sep(r_sep.handle());
  dds::WaitSet ws;
  ws.attach(stop.handle(), 0);
  ws.attach(liveliness_changed.handle(), 1);
  ws.attach(rc_kf.handle(), 2);
  ws.attach(rc_loop.handle(), 3);
  ws.attach(rc_central.handle(), 4);
  ws.attach(rc_sep.handle(), 5);
  std::optional<dds::ReadCondition> rc_loop_local;
  if (r_loop_local) {
    rc_loop_local.emplace(r_loop_local->handle());
    ws.attach(rc_loop_local->handle(), 6);
  }

  dds::ValidationLimits limits;
  limits.robot_count = o.core.robot_count;
  limits.extra_node_ids = {o.central_id};
  dds::RejectionCounter rejected;
  const auto t0 = Clock::now();
  auto now_ns = [&] { return std::chrono::duration_cast<Nanos>(Clock::now() - t0); };
  PeerCore core(o.core, now_ns());
  std::map<uint32_t, StoredKeyframe> own_keyframes;
  std::map<uint32_t, cdc_msg_LoopClosure> own_loops;
  uint32_t incarnation = 0;
  uint64_t resent_keyframes = 0, resent_loops = 0, corrections = 0, separators_sent = 0, forwarded_keyframes = 0,
           withheld_keyframes = 0, kf_writer_discards = 0;
  auto last_status = Clock::now() - std::chrono::hours(1);
  auto last_mode = last_status;
  auto last_radio_status = last_status;
  std::vector<cdc_msg_KeyframePose> pose_storage;
  std::vector<cdc_msg_KeyframePoseF> separator_storage;
  std::map<uint32_t, Eigen::Isometry3d> latest_world;  // own keyframes, T_world, as last corrected
  int64_t sim_stamp_ns = 0;                            // newest own keyframe's data time
  std::ofstream mode_log;
  if (!o.mode_out.empty()) {
    mode_log.open(o.mode_out);
    if (!mode_log) throw std::runtime_error(o.mode_out + ": cannot write the mode timeline");
    mode_log << "wall_ns,sim_ns,robot,from,to,reason,distance_m,keyframes\n" << std::flush;
  }
  spdlog::info("peer optimiser of robot {} up: CR_0 {} m, dwell {} ms, mask {} ms, domain {}{}", me,
               o.core.rtdos.range_m, o.core.rtdos.dwell.count() / 1'000'000, o.core.rtdos.mask.count() / 1'000'000,
               o.domain,
               domains.split() ? ", own keyframes, loops and corrections on local domain " + std::to_string(o.local_domain)
                               : std::string());

  // distance: the one the switch was decided on (the estimate can move within the same step).
  auto publish_mode = [&](SwitchReason reason, std::optional<double> distance) {
    cdc_msg_ModeState m{};
    m.robot_id = me;
    m.incarnation = incarnation;
    m.stamp_ns = dds::now_ns();
    m.mode = to_msg(core.mode());
    m.reason = to_msg(reason);
    m.distance_to_central = distance.value_or(-1.0);
    m.transition_count = core.rtdos().transitions();
    w_mode.write(m);
  };

  // MODE_OUT.now: "<mode> <keyframes> <transitions> <central alive 0|1> <keyframes acknowledged>",
  // replaced atomically, for a launcher that charges traffic to the mode it reads there (so it is
  // written at once on a switch, before the re-sends that follow one) and ends a rendezvous once the
  // central holds every keyframe (acknowledged: the central's highest contiguous keyframe id + 1).
  auto write_now = [&](bool alive) {
    if (o.mode_out.empty()) return;
    const std::string now_path = o.mode_out + ".now", tmp = now_path + ".tmp";
    std::ofstream(tmp, std::ios::trunc) << to_string(core.mode()) << ' ' << own_keyframes.size() << ' '
                                        << core.rtdos().transitions() << ' ' << (alive ? 1 : 0) << ' '
                                        << core.central_acknowledged_keyframe() + 1 << '\n';
    std::rename(tmp.c_str(), now_path.c_str());
  };

  while (!dds::ShutdownSignal::requested()) {
    ws.wait(std::chrono::milliseconds(o.tick_ms));
    liveliness_changed.reset();
    const Nanos now = now_ns();
    r_kf.take(1024).for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
      if (m.robot_id != me) {
        return;
      }
      if (rejected.record(topics::kKeyframe, dds::validate(m, limits))) {
        spdlog::warn("rejected keyframe: {}", rejected.last_reason());
        return;
      }
      incarnation = m.incarnation;
      sim_stamp_ns = std::max(sim_stamp_ns, m.stamp_ns);
      StoredKeyframe& s = own_keyframes[m.keyframe_id];
      s.msg = m;
      s.cloud.assign(m.cloud._buffer, m.cloud._buffer + m.cloud._length);
      s.msg.cloud = {};
      core.add_keyframe(OwnKeyframe{m.keyframe_id, m.incarnation, dds::to_eigen(m.T_odom_keyframe),
                                    dds::to_eigen(m.T_prev_keyframe), dds::information_to_eigen(m.information)},
                        now);
      // The central (and its map) read keyframes on the SLAM domain. Only a CENTRALIZED robot sends
      // them: a DISTRIBUTED one exchanges descriptors and separators only, and its keyframes reach the
      // central as the backlog it re-sends on rejoining (all the central has not acknowledged).
      if (domains.split()) {
        if (core.mode() == Mode::kCentralized) {
          w_kf.write(m);
          ++forwarded_keyframes;
        } else {
          ++withheld_keyframes;
        }
      }
    });
    auto on_loop = [&](const cdc_msg_LoopClosure& m, const dds_sample_info_t&) {
      if (m.robot_a != me && m.robot_b != me) {
        return;
      }
      if (rejected.record(topics::kLoopClosure, dds::validate(m, limits))) {
        spdlog::warn("rejected loop closure: {}", rejected.last_reason());
        return;
      }
      if (m.sender_robot_id == me) {
        own_loops[m.loop_seq] = m;
      }
      core.add_loop(LoopRecord{m.sender_robot_id, m.sender_incarnation, m.loop_seq, m.robot_a, m.keyframe_a, m.robot_b,
                               m.keyframe_b, m.status == cdc_msg_LOOP_WITHDRAWN, dds::to_eigen(m.T_a_b),
                               dds::information_to_eigen(m.information)},
                    now);
    };
    r_loop.take(1024).for_each_valid(on_loop);
    if (r_loop_local) r_loop_local->take(1024).for_each_valid(on_loop);
    r_central.take(64).for_each_valid([&](const cdc_msg_OptimizedPoses& m, const dds_sample_info_t&) {
      if (m.robot_id != me) {
        return;
      }
      if (rejected.record(topics::kCentralOptimized, dds::validate(m, limits))) {
        spdlog::warn("rejected central result: {}", rejected.last_reason());
        return;
      }
      CentralResult r;
      r.central_incarnation = m.sender_incarnation;
      r.version = m.graph_version;
      r.T_world_robot = dds::to_eigen(m.T_world_robot);
      r.from_hint = m.source == cdc_msg_SOURCE_CENTRAL_HINT;
      for (uint32_t i = 0; i < m.poses._length; ++i) {
        r.poses.emplace_back(m.poses._buffer[i].keyframe_id, dds::to_eigen(m.poses._buffer[i].pose));
      }
      core.on_central_result(r);
    });
    r_ack.take(64).for_each_valid([&](const cdc_msg_Acknowledgement& m, const dds_sample_info_t&) {
      if (m.robot_id == me && !rejected.record(topics::kCentralAck, dds::validate(m, limits))) {
        core.on_ack(AckIn{m.central_incarnation, m.robot_incarnation, m.highest_contiguous_keyframe,
                          m.highest_contiguous_loop_seq});
      }
    });
    r_sep.take(256).for_each_valid([&](const cdc_msg_SeparatorPoses& m, const dds_sample_info_t&) {
      if (m.target_robot_id != me) {
        return;
      }
      if (rejected.record(topics::kSeparator, dds::validate(m, limits))) {
        spdlog::warn("rejected separator poses: {}", rejected.last_reason());
        return;
      }
      std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;
      for (uint32_t i = 0; i < m.poses._length; ++i) {
        poses.emplace_back(m.poses._buffer[i].keyframe_id, dds::to_eigen(m.poses._buffer[i].pose));
      }
      core.on_separator(m.robot_id, poses);
    });
    r_status.take(64).for_each_valid([&](const cdc_msg_RobotStatus& m, const dds_sample_info_t&) {
      if (m.robot_id == me || rejected.record(topics::kRobotStatus, dds::validate(m, limits))) {
        return;
      }
      if (!m.is_central) {
        core.on_peer_mode(m.robot_id, from_msg(m.mode));
      }
      if (!m.world_valid) return;
      const Eigen::Vector3d p = dds::to_eigen(m.T_world_base.position);
      if (m.is_central) {
        core.on_central_position(p);
      } else {
        core.on_peer_position(m.robot_id, p);
      }
    });

    // A peer's reader matched anew (it came back in reach after its lease lapsed, or restarted)
    // has missed the separators written while it was away: it gets all of them next round.
    for (uint32_t r = 0; r < w_sep.size(); ++r) {
      if (const dds::Writer<cdc_msg_SeparatorPoses>* w = w_sep.to(r)) {
        const uint32_t matched = w->readers_ever_matched();
        if (matched != sep_matches[r]) {
          sep_matches[r] = matched;
          core.resend_separators_to(r);
        }
      }
    }
    const bool alive = central_liveliness.state() == dds::Liveliness::kAlive;
    StepOutput out = core.step(now, alive);
    if (out.transition) {
      spdlog::info("mode {} -> {} ({}), distance to central {}", to_string(out.transition->from),
                   to_string(out.transition->to), to_string(out.transition->reason),
                   out.transition->distance_m ? std::to_string(*out.transition->distance_m) + " m" : "unknown");
      publish_mode(out.transition->reason, out.transition->distance_m);
      last_mode = Clock::now();
      last_radio_status = Clock::time_point{};  // peers learn the new mode at once (separators follow it)
      write_now(alive);
      if (out.transition->to == Mode::kDistributed && domains.split()) {
        // Keyframes forwarded since the link to the central was cut (until its lease lapsed) are
        // unacknowledged: dropped here, they reach the central as the backlog re-sent on rejoining,
        // not by DDS as soon as the link returns while this robot is still DISTRIBUTED.
        w_kf.discard_unacknowledged();
        ++kf_writer_discards;
      }
      if (mode_log.is_open()) {
        mode_log << dds::now_ns() << ',' << sim_stamp_ns << ',' << me << ',' << to_string(out.transition->from) << ','
                 << to_string(out.transition->to) << ',' << to_string(out.transition->reason) << ','
                 << (out.transition->distance_m ? std::to_string(*out.transition->distance_m) : std::string("")) << ','
                 << own_keyframes.size() << '\n'
                 << std::flush;
      }
    } else if (Clock::now() - last_mode >= std::chrono::milliseconds(o.mode_period_ms)) {
      publish_mode(core.rtdos().last_reason(), core.distance_to_central());
      last_mode = Clock::now();
    }
    if (out.world_transform) {
      cdc_msg_WorldTransform w{};
      w.robot_id = me;
      w.incarnation = incarnation;
      w.stamp_ns = dds::now_ns();
      w.source = cdc_msg_SOURCE_DISTRIBUTED;
      w.graph_version = core.distributed_rounds();
      w.T_world_robot = dds::to_msg(*out.world_transform);
      w_world.write(w);
    }
    for (uint32_t id : out.resend_keyframes) {
      auto it = own_keyframes.find(id);
      if (it != own_keyframes.end()) {
        cdc_msg_Keyframe m = it->second.msg;
        dds::borrow(m.cloud, it->second.cloud);
        w_kf.write(m);
        ++resent_keyframes;
      }
    }
    for (uint32_t seq : out.resend_loops) {
      auto it = own_loops.find(seq);
      if (it != own_loops.end()) {
        w_loop.write(it->second);
        ++resent_loops;
      }
    }
    if (!out.resend_keyframes.empty() || !out.resend_loops.empty()) {
      spdlog::info("re-sent {} keyframes and {} loop closures the central had not acknowledged",
                   out.resend_keyframes.size(), out.resend_loops.size());
    }
    for (const SeparatorOut& s : out.separators) {
      dds::Writer<cdc_msg_SeparatorPoses>* to = w_sep.to(s.target);
      if (to == nullptr) continue;  // targets are robots of validated loops, never this robot
      separator_storage.clear();
      for (const auto& [id, T] : s.poses) {
        separator_storage.push_back(cdc_msg_KeyframePoseF{id, dds::to_msg_f(T)});
      }
      cdc_msg_SeparatorPoses m{};
      m.robot_id = me;
      m.target_robot_id = s.target;
      m.incarnation = incarnation;
      m.round = static_cast<uint32_t>(core.distributed_rounds());
      m.stamp_ns = dds::now_ns();
      dds::borrow(m.poses, separator_storage);
      to->write(m);
      ++separators_sent;
    }
    if (out.correction) {
      pose_storage.clear();
      for (const auto& [id, T] : out.correction->poses) {
        pose_storage.push_back(cdc_msg_KeyframePose{me, id, dds::to_msg(T)});
        latest_world[id] = T;
      }
      cdc_msg_OptimizedPoses m{};
      m.robot_id = me;
      m.sender_robot_id = me;
      m.sender_incarnation = incarnation;
      m.graph_version = corrections;
      m.stamp_ns = dds::now_ns();
      m.source = out.correction->from_central ? cdc_msg_SOURCE_CENTRAL : cdc_msg_SOURCE_DISTRIBUTED;
      m.T_world_robot = dds::to_msg(out.correction->T_world_robot);
      dds::borrow(m.poses, pose_storage);
      w_corr.write(m);
      ++corrections;
      if (spdlog::should_log(spdlog::level::debug) && !out.correction->poses.empty()) {
        // What the front-end takes: T_world_robot, and the newest keyframe in its odometry frame.
        const Eigen::Isometry3d& T = out.correction->T_world_robot;
        const Eigen::AngleAxisd r(T.linear());
        const Eigen::Vector3d rv = r.angle() * r.axis() * 1e3;
        const auto& [id, P] = out.correction->poses.back();
        const Eigen::Vector3d w = P.translation(), l = (T.inverse() * P).translation();
        spdlog::debug("correction {} ({}, lambda {:.3f}): T_world_robot ({:.3f}, {:.3f}, {:.3f}) m ({:.3f}, {:.3f}, {:.3f}) mrad; "
                      "keyframe {} at ({:.3f}, {:.3f}, {:.3f}) in W, ({:.3f}, {:.3f}, {:.3f}) in L",
                      corrections, out.correction->from_central ? "central" : "distributed", out.correction->lambda,
                      T.translation().x(), T.translation().y(), T.translation().z(), rv.x(), rv.y(), rv.z(), id, w.x(),
                      w.y(), w.z(), l.x(), l.y(), l.z());
      }
    }
    if (Clock::now() - last_radio_status >= std::chrono::milliseconds(o.radio_status_period_ms)) {
      cdc_msg_RobotStatus s{};
      s.robot_id = me;
      s.incarnation = incarnation;
      s.stamp_ns = dds::now_ns();
      const auto pose = core.world_pose();
      s.world_valid = pose.has_value();
      s.T_world_base = dds::to_msg(pose.value_or(Eigen::Isometry3d::Identity()));
      s.last_keyframe_id = core.last_keyframe_id();
      s.mode = to_msg(core.mode());
      s.is_central = false;
      w_status.write(s);
      last_radio_status = Clock::now();
    }
    if (Clock::now() - last_status >= std::chrono::milliseconds(o.status_period_ms)) {
      last_status = Clock::now();
      write_now(alive);
    }
  }
  dds::ShutdownSignal::remove_guard(&stop);
  central_liveliness.set_notify(nullptr);
  if (!o.trajectory_out.empty()) {
    std::map<uint32_t, Eigen::Isometry3d> T_odom;
    for (const auto& [id, kf] : own_keyframes) T_odom[id] = dds::to_eigen(kf.msg.T_odom_keyframe);
    geometry::Trajectory traj;
    for (const auto& [id, T] : complete_world_poses(T_odom, latest_world)) {
      traj.push_back({own_keyframes.at(id).msg.stamp_ns, T});
    }
    geometry::write_tum(o.trajectory_out, traj);
  }
  if (!o.graph_out.empty()) {
    graph::write_g2o(o.graph_out, core.graph());
  }
  if (!o.stats_out.empty()) {
    nlohmann::json j{{"robot", me},
                     {"transitions", core.rtdos().transitions()},
                     {"mode", to_string(core.mode())},
                     {"keyframes", own_keyframes.size()},
                     {"resent_keyframes", resent_keyframes},
                     {"resent_loops", resent_loops},
                     {"forwarded_keyframes", forwarded_keyframes},
                     {"withheld_keyframes", withheld_keyframes},
                     {"keyframe_writer_discards", kf_writer_discards},
                     {"radio_cuts", domains.radio_cuts()},
                     {"corrections", corrections},
                     {"separator_messages", separators_sent},
                     {"distributed_rounds", core.distributed_rounds()},
                     {"rejected_samples", rejected.total()}};
    j["topics"] = dds::topic_traffic_json();
    std::ofstream(o.stats_out) << j.dump(2) << '\n';
  }
  spdlog::info("stopped (signal {})", dds::ShutdownSignal::signal_number());
  return 0;
}

}  // namespace cdc::peer
