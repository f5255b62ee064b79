#include "central_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/objective.hpp"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <chrono>
#include <deque>
#include <fstream>
#include <random>

namespace cdc::central {
namespace {

using Clock = std::chrono::steady_clock;
namespace topics = dds::topics;

uint32_t draw_incarnation() {
  std::random_device rd;
  uint32_t v = 0;
  while (v == 0) {
    v = rd();
  }
  return v;
}

KeyframeIn to_core(const cdc_msg_Keyframe& m) {
  KeyframeIn k;
  k.robot = m.robot_id;
  k.incarnation = m.incarnation;
  k.id = m.keyframe_id;
  k.stamp_ns = m.stamp_ns;
  k.T_odom_keyframe = dds::to_eigen(m.T_odom_keyframe);
  k.T_prev_keyframe = dds::to_eigen(m.T_prev_keyframe);
  k.information = dds::information_to_eigen(m.information);
  return k;
}

LoopIn to_core(const cdc_msg_LoopClosure& m) {
  LoopIn l;
  l.sender = m.sender_robot_id;
  l.sender_incarnation = m.sender_incarnation;
  l.seq = m.loop_seq;
  l.robot_a = m.robot_a;
  l.keyframe_a = m.keyframe_a;
  l.robot_b = m.robot_b;
  l.keyframe_b = m.keyframe_b;
  l.withdrawn = m.status == cdc_msg_LOOP_WITHDRAWN;
  l.T_a_b = dds::to_eigen(m.T_a_b);
  l.information = dds::information_to_eigen(m.information);
  return l;
}

}  // namespace

CentralNodeOptions load_options(const std::string& path) {
  CentralNodeOptions o;
  config::Reader r(path);
  auto positive = [](const int& v) { return v > 0; };
  int robots = static_cast<int>(o.core.robot_count);
  r.get<int>("robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.core.robot_count = static_cast<uint32_t>(robots);
  int central_id = static_cast<int>(o.central_id);
  r.get<int>("central_id", central_id, [](const int& v) { return v >= 0 && v <= 254; }, "0..254");
  o.central_id = static_cast<uint32_t>(central_id);
  r.get<int>("central_on_robot", o.central_on_robot, [](const int& v) { return v >= -1 && v <= 254; }, "-1 or a robot id");
  std::vector<double> pos{0, 0, 0};
  r.get<std::vector<double>>("central_position", pos, [](const std::vector<double>& v) { return v.size() == 3; },
                             "[x, y, z]");
  o.central_position = Eigen::Vector3d(pos[0], pos[1], pos[2]);
  r.get<int>("lease_ms", o.lease_ms, [](const int& v) { return v >= 50 && v <= 60000; }, "50..60000");
  r.get<int>("update_period_ms", o.update_period_ms, positive, "> 0");
  r.get<int>("status_period_ms", o.status_period_ms, positive, "> 0");
  r.get<int>("max_result_age_ms", o.max_result_age_ms, positive, "> 0");
  r.get<int>("optimiser.max_iterations", o.core.max_iterations_per_update, positive, "> 0");
  double max_time_ms = o.core.max_time_per_update_s * 1e3;
  r.get<double>("optimiser.max_time_ms", max_time_ms, [](const double& v) { return v > 0; }, "> 0");
  o.core.max_time_per_update_s = max_time_ms * 1e-3;
  r.get<uint32_t>("optimiser.window", o.core.window);
  r.get<uint32_t>("optimiser.full_every", o.core.full_every, [](const uint32_t& v) { return v >= 1; }, ">= 1");
  r.get<int>("optimiser.full_pass_iterations", o.core.full_pass_iterations, positive, "> 0");
  double full_pass_ms = o.core.full_pass_time_s * 1e3;
  r.get<double>("optimiser.full_pass_time_ms", full_pass_ms, [](const double& v) { return v > 0; }, "> 0");
  o.core.full_pass_time_s = full_pass_ms * 1e-3;
  r.get<double>("optimiser.loop_robust_scale", o.core.loop_robust_scale, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<bool>("optimiser.share_loop_information", o.core.share_loop_information);
  r.get<std::string>("log_level", o.log_level);
  if (o.central_on_robot >= robots) {
    r.error("central_on_robot " + std::to_string(o.central_on_robot) + " is not one of the " + std::to_string(robots) +
            " robots");
  }
  r.finish();
  return o;
}

int run_central(const CentralNodeOptions& o) {
  const uint32_t incarnation = draw_incarnation();
  dds::ParticipantOptions po;
  po.domain_id = o.domain;
  po.config = o.dds_config;
  dds::Participant participant(po);

  dds::Topic<cdc_msg_Keyframe> t_kf(participant, topics::kKeyframe);
  dds::Topic<cdc_msg_LoopClosure> t_loop(participant, topics::kLoopClosure);
  dds::Topic<cdc_msg_WorldTransform> t_world(participant, topics::kWorldTransform);
  dds::Topic<cdc_msg_OptimizedPoses> t_opt(participant, topics::kCentralOptimized);
  dds::Topic<cdc_msg_Acknowledgement> t_ack(participant, topics::kCentralAck);
  dds::Topic<cdc_msg_RobotStatus> t_status(participant, topics::kRobotStatus);

  dds::Reader<cdc_msg_Keyframe> r_kf(participant, t_kf, dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader()));
  dds::Reader<cdc_msg_LoopClosure> r_loop(participant, t_loop,
                                          dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader()));
  dds::Reader<cdc_msg_WorldTransform> r_world(participant, t_world, dds::qos::keyed_state());
  // The optimiser's liveliness, asserted from the loop below (a hung optimiser lapses too), on a
  // topic of its own that every robot's monitor reads. It also carries the central's status, written
  // every status period: a robot's Cyclone brings a writer whose lease lapsed back to life on data,
  // not on assertions, so without data a robot cut off for less than the participant lease (10 s)
  // never saw the central alive again when the link returned. Each robot's results go in the
  // robot's own partition, so that a robot receives only its own poses (the map reads all).
  dds::Topic<cdc_msg_RobotStatus> t_alive(participant, topics::kCentralAlive);
  dds::Writer<cdc_msg_RobotStatus> w_alive(participant, t_alive,
                                           dds::qos::monitored_writer(std::chrono::milliseconds(o.lease_ms)));
  std::deque<dds::Writer<cdc_msg_OptimizedPoses>> w_results;
  for (uint32_t k = 0; k < o.core.robot_count; ++k) {
    w_results.emplace_back(participant, t_opt, dds::qos::keyed_state(1).partitions({dds::partitions::robot(k)}));
  }
  dds::Writer<cdc_msg_Acknowledgement> w_ack(participant, t_ack, dds::qos::keyed_state());
  dds::Writer<cdc_msg_RobotStatus> w_status(participant, t_status, dds::qos::keyed_state());

  dds::GuardCondition stop(participant);
  dds::ShutdownSignal::add_guard(&stop);
  dds::ReadCondition rc_kf(r_kf.handle()), rc_loop(r_loop.handle()), rc_world(r_world.handle());
  dds::WaitSet ws(participant);
  ws.attach(stop.handle(), 0);
  ws.attach(rc_kf.handle(), 1);
  ws.attach(rc_loop.handle(), 2);
  ws.attach(rc_world.handle(), 3);

  CentralCore core(o.core);
  dds::ValidationLimits limits;
  limits.robot_count = o.core.robot_count;
  dds::RejectionCounter rejected;
  spdlog::info("central optimiser up: incarnation {}, {} robots, lease {} ms, domain {}", incarnation,
               o.core.robot_count, o.lease_ms, o.domain);

  auto last_update = Clock::now() - std::chrono::hours(1);
  auto last_status = last_update, last_results = last_update;
  uint64_t updates = 0, unsettled_updates = 0, results_held = 0;
  Eigen::Vector3d central_position = o.central_position;
  // The results writer's liveliness is asserted from this loop: a hung optimiser lapses too.
  const auto tick = std::chrono::milliseconds(std::max(10, o.lease_ms / 5));
  std::vector<cdc_msg_KeyframePose> pose_storage;
  bool acks_dirty = false;

  while (!dds::ShutdownSignal::requested()) {
    ws.wait(tick);
    w_alive.assert_liveliness();
    r_kf.take(1024).for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
      if (rejected.record(topics::kKeyframe, dds::validate(m, limits))) {
        spdlog::warn("rejected keyframe: {}", rejected.last_reason());
        return;
      }
      const AddResult r = core.add_keyframe(to_core(m));
      acks_dirty = acks_dirty || r.outcome == Outcome::kAccepted;
    });
    r_loop.take(1024).for_each_valid([&](const cdc_msg_LoopClosure& m, const dds_sample_info_t&) {
      if (rejected.record(topics::kLoopClosure, dds::validate(m, limits))) {
        spdlog::warn("rejected loop closure: {}", rejected.last_reason());
        return;
      }
      const AddResult r = core.add_loop(to_core(m));
      if (r.outcome == Outcome::kRejected) {
        rejected.record(topics::kLoopClosure, dds::Validation::fail(r.reason));
        spdlog::warn("rejected loop closure: {}", r.reason);
      }
      acks_dirty = acks_dirty || r.outcome == Outcome::kAccepted;
    });
    r_world.take().for_each_valid([&](const cdc_msg_WorldTransform& m, const dds_sample_info_t&) {
      if (rejected.record(topics::kWorldTransform, dds::validate(m, limits))) {
        spdlog::warn("rejected world transform: {}", rejected.last_reason());
        return;
      }
      core.add_world_hint(m.robot_id, m.incarnation, dds::to_eigen(m.T_world_robot));
    });

    const auto now = Clock::now();
    if ((core.dirty() || !core.settled()) && now - last_update >= std::chrono::milliseconds(o.update_period_ms)) {
      const UpdateStats u = core.optimise();
      w_alive.assert_liveliness();
      if (spdlog::should_log(spdlog::level::debug)) {
        spdlog::debug("update {} (graph version {}): {} pass over {} poses and {} factors, {} iterations in {:.0f} ms, {}",
                      updates + 1, core.version(), u.full ? "full" : "local", u.poses, u.factors, u.iterations,
                      u.time_s * 1e3, u.converged ? "converged" : "not converged");
      }
      last_update = now;
      ++updates;
      // A graph that has not settled (a bounded pass after a large change, such as a robot's
      // re-sent backlog) is a partial solution: its results are held back, so that the robots'
      // front-ends never follow it and then turn back, unless the last results are getting old.
      const bool publish = core.settled() || now - last_results >= std::chrono::milliseconds(o.max_result_age_ms);
      if (!core.settled()) ++unsettled_updates;
      if (!publish) {
        ++results_held;
      } else {
        last_results = now;
        for (const RobotEstimate& e : core.estimates()) {
          pose_storage.clear();
          for (const auto& [id, T] : e.poses) {
            pose_storage.push_back(cdc_msg_KeyframePose{e.robot, id, dds::to_msg(T)});
          }
          cdc_msg_OptimizedPoses msg{};
          msg.robot_id = e.robot;
          msg.sender_robot_id = o.central_id;
          msg.sender_incarnation = incarnation;
          msg.graph_version = core.version();
          msg.stamp_ns = dds::now_ns();
          msg.source = e.from_hint ? cdc_msg_SOURCE_CENTRAL_HINT : cdc_msg_SOURCE_CENTRAL;
          msg.T_world_robot = dds::to_msg(e.T_world_robot);
          dds::borrow(msg.poses, pose_storage);
          w_results.at(e.robot).write(msg);
          if (spdlog::should_log(spdlog::level::debug) && !e.poses.empty()) {
            // The result as the robot's front-end takes it: T_world_robot, the newest keyframe in W and in L.
            const Eigen::Isometry3d& T = e.T_world_robot;
            const Eigen::AngleAxisd r(T.linear());
            const Eigen::Vector3d rv = r.angle() * r.axis() * 1e3;
            const auto& [id, P] = e.poses.back();
            const Eigen::Vector3d w = P.translation(), l = (T.inverse() * P).translation();
            spdlog::debug("graph version {}: robot {}{}: T_world_robot ({:.3f}, {:.3f}, {:.3f}) m ({:.3f}, {:.3f}, {:.3f}) mrad; "
                          "newest keyframe {} at ({:.3f}, {:.3f}, {:.3f}) in W, ({:.3f}, {:.3f}, {:.3f}) in L",
                          core.version(), e.robot, e.from_hint ? " (hint)" : "", T.translation().x(), T.translation().y(),
                          T.translation().z(), rv.x(), rv.y(), rv.z(), id, w.x(), w.y(), w.z(), l.x(), l.y(), l.z());
          }
          if (static_cast<int>(e.robot) == o.central_on_robot && !e.poses.empty()) {
            central_position = e.poses.back().second.translation();
          }
        }
      }
    }
    if (acks_dirty) {
      for (const Acknowledgement& a : core.acknowledgements()) {
        cdc_msg_Acknowledgement m{};
        m.robot_id = a.robot;
        m.robot_incarnation = a.incarnation;
        m.central_incarnation = incarnation;
        m.stamp_ns = dds::now_ns();
        m.highest_contiguous_keyframe = a.highest_contiguous_keyframe;
        m.highest_contiguous_loop_seq = a.highest_contiguous_loop_seq;
        w_ack.write(m);
      }
      acks_dirty = false;
    }
    if (now - last_status >= std::chrono::milliseconds(o.status_period_ms)) {
      cdc_msg_RobotStatus s{};
      s.robot_id = o.central_id;
      s.incarnation = incarnation;
      s.stamp_ns = dds::now_ns();
      s.world_valid = true;
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.translation() = central_position;
      s.T_world_base = dds::to_msg(T);
      s.last_keyframe_id = -1;
      s.mode = cdc_msg_MODE_CENTRALIZED;
      s.is_central = true;
      w_status.write(s);
      w_alive.write(s);
      last_status = now;
    }
  }
  dds::ShutdownSignal::remove_guard(&stop);

  spdlog::info("shutting down (signal {}): final optimisation", dds::ShutdownSignal::signal_number());
  const UpdateStats final_stats = core.optimise_fully();
  if (!o.graph_out.empty()) {
    graph::write_g2o(o.graph_out, core.graph());
  }
  if (!o.stats_out.empty()) {
    const Counters& c = core.counters();
    nlohmann::json j{{"incarnation", incarnation},
                     {"keyframes_accepted", c.keyframes_accepted},
                     {"keyframes_duplicate", c.keyframes_duplicate},
                     {"keyframes_rejected", c.keyframes_rejected},
                     {"loops_accepted", c.loops_accepted},
                     {"loops_duplicate", c.loops_duplicate},
                     {"loops_rejected", c.loops_rejected},
                     {"loops_withdrawn", c.loops_withdrawn},
                     {"rejected_samples", rejected.total()},
                     {"graph_poses", core.graph().poses.size()},
                     {"graph_factors", core.graph().factors.size()},
                     {"updates", updates},
                     {"unsettled_updates", unsettled_updates},
                     {"results_held", results_held},
                     {"final_cost", final_stats.cost}};
    nlohmann::json acks = nlohmann::json::array();
    for (const Acknowledgement& a : core.acknowledgements()) {
      acks.push_back({{"robot", a.robot},
                      {"incarnation", a.incarnation},
                      {"highest_contiguous_keyframe", a.highest_contiguous_keyframe},
                      {"highest_contiguous_loop_seq", a.highest_contiguous_loop_seq},
                      {"keyframes_held", core.keyframes_held(a.robot, a.incarnation)}});
    }
    j["sessions"] = acks;
    j["topics"] = dds::topic_traffic_json();
    std::ofstream(o.stats_out) << j.dump(2) << '\n';
  }
  return 0;
}

}  // namespace cdc::central
