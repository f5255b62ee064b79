#include "central_node.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/runtime/logging.hpp"
#include "cdc/runtime/memory.hpp"
#include "cdc/runtime/stats.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <random>

namespace cdc::central {

NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(Counters, keyframes_accepted, keyframes_duplicate, keyframes_rejected,
                                   keyframes_pending_full, loops_accepted, loops_duplicate, loops_rejected,
                                   loops_withdrawn, loops_outliers)

namespace {

using Clock = UpdateSchedule::Clock;
namespace topics = dds::topics;

uint32_t draw_incarnation() {
  std::random_device rd;
  uint32_t v = 0;
  while (v == 0) v = rd();
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

// The result as the robot's front-end takes it.
void log_result(uint64_t version, const RobotEstimate& e) {
  if (!spdlog::should_log(spdlog::level::debug) || e.poses.empty()) return;
  spdlog::debug("graph version {}: robot {}{}: {}", version, e.robot, e.from_hint ? " (hint)" : "",
                runtime::world_estimate_text(e.T_world_robot, e.poses.back().first, e.poses.back().second));
}

}  // namespace

// The optimiser's liveliness is asserted by a watchdog thread every quarter lease while the work loop has
// made progress within hang_timeout_ms (a hung optimiser lapses too; a whole-graph pass of a long
// mission on a loaded machine does not), on a topic of its own that every robot's monitor reads. It also carries the
// central's status, written every status period: a robot's Cyclone brings a writer whose lease lapsed back to life on
// data, not on assertions, so without data a robot cut off for less than the participant lease (10 s) would never see
// the central alive again when the link returned. Each robot's results go in the robot's own partition, so that a robot
// receives only its own poses (the map reads all).
CentralNode::CentralNode(const runtime::ServiceOptions& common, const CentralNodeOptions& o)
    : o_(o),
      incarnation_(draw_incarnation()),
      service_(runtime::Domains::kSingle, common, runtime::swarm_limits(o.core.robot_count)),
      keyframes_(service_, service_.radio(), topics::kKeyframe,
                 dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader())),
      loops_(service_, service_.radio(), topics::kLoopClosure,
             dds::qos::event_stream(4096).partitions(dds::partitions::all_robots_reader())),
      world_(service_, service_.radio(), topics::kWorldTransform, dds::qos::keyed_state()),
      t_opt_(service_.radio(), topics::kCentralOptimized),
      w_alive_(service_.radio(), topics::kCentralAlive,
               dds::qos::monitored_writer(std::chrono::milliseconds(o.lease_ms))),
      w_ack_(service_.radio(), topics::kCentralAck, dds::qos::keyed_state()),
      w_status_(service_.radio(), topics::kRobotStatus, dds::qos::keyed_state()),
      core_(o.core),
      schedule_(std::chrono::milliseconds(o.update_period_ms), std::chrono::milliseconds(o.max_result_age_ms)),
      pacer_(o.core.robot_count, o.result_pose_rate),
      last_status_(Clock::now() - std::chrono::hours(1)) {
  for (uint32_t k = 0; k < o.core.robot_count; ++k) {
    w_results_.emplace_back(service_.radio(), t_opt_, dds::qos::keyed_state(1).partitions({dds::partitions::robot(k)}));
  }
  keyframes_.on([this](const cdc_msg_Keyframe& m) { on_keyframe(m); });
  loops_.on([this](const cdc_msg_LoopClosure& m) { on_loop(m); });
  world_.on([this](const cdc_msg_WorldTransform& m) { on_world(m); });
  core_.on_iteration([this] { progressed(); });
  progressed();
  watchdog_ = std::thread([this] { watch(); });
  spdlog::info("central optimiser up: incarnation {}, {} robots, lease {} ms, domain {}", incarnation_,
               o.core.robot_count, o.lease_ms, common.domain_id());
}

CentralNode::~CentralNode() {
  stopping_ = true;
  if (watchdog_.joinable()) watchdog_.join();
}

void CentralNode::watch() {
  const auto period = std::chrono::milliseconds(std::max(10, o_.lease_ms / 4));
  const int64_t hang_ns = int64_t{o_.hang_timeout_ms} * 1'000'000;
  while (!stopping_) {
    const int64_t now = std::chrono::steady_clock::now().time_since_epoch().count();
    if (now - progress_ns_.load() < hang_ns) w_alive_.assert_liveliness();
    std::this_thread::sleep_for(period);
  }
}

void CentralNode::spin() {
  const auto tick = std::chrono::milliseconds(std::max(10, o_.lease_ms / 5));
  while (service_.wait(tick)) {
    progressed();
    take_inputs();
    const auto now = Clock::now();
    if (schedule_.update_due(core_.dirty(), core_.settled(), now)) optimise(now);
    publish_due_results(Clock::now());
    if (acks_dirty_) publish_acknowledgements();
    if (now - last_status_ >= std::chrono::milliseconds(o_.status_period_ms)) {
      publish_status();
      last_status_ = now;
    }
  }
}

// A bounded batch of each input per wake-up (each sample costs the core O(log n)), liveliness asserted
// after each: a flood waits in the readers' history, not in the work loop.
void CentralNode::take_inputs() {
  keyframes_.poll(1024);
  progressed();
  loops_.poll(1024);
  progressed();
  world_.poll();
}

void CentralNode::on_keyframe(const cdc_msg_Keyframe& m) {
  const AddResult r = core_.add_keyframe(to_core(m));
  if (r.outcome == Outcome::kRejected) service_.boundary().refuse(topics::kKeyframe, dds::Validation::fail(r.reason));
  acks_dirty_ = acks_dirty_ || r.outcome == Outcome::kAccepted;
}

void CentralNode::on_loop(const cdc_msg_LoopClosure& m) {
  const AddResult r = core_.add_loop(to_core(m));
  if (r.outcome == Outcome::kRejected)
    service_.boundary().refuse(topics::kLoopClosure, dds::Validation::fail(r.reason));
  acks_dirty_ = acks_dirty_ || r.outcome == Outcome::kAccepted;
}

void CentralNode::on_world(const cdc_msg_WorldTransform& m) {
  core_.add_world_hint(m.robot_id, m.incarnation, dds::to_eigen(m.T_world_robot));
}

void CentralNode::optimise(Clock::time_point now) {
  const UpdateStats u = core_.optimise();
  if (u.full) runtime::release_free_memory();  // a whole-graph pass's buffers grow with the graph
  progressed();
  record_update_time(std::chrono::duration<double, std::milli>(Clock::now() - now).count());
  spdlog::debug("update {} (graph version {}): {} pass over {} poses and {} factors, {} iterations in {:.0f} ms, {}",
                schedule_.updates() + 1, core_.version(), u.full ? "full" : "local", u.poses, u.factors, u.iterations,
                u.time_s * 1e3, u.converged ? "converged" : "not converged");
  if (schedule_.updated(core_.settled(), now)) pacer_.updated();
}

void CentralNode::publish_due_results(Clock::time_point now) {
  for (uint32_t robot = 0; robot < o_.core.robot_count; ++robot) {
    if (!pacer_.due(robot, now)) continue;
    const std::optional<RobotEstimate> e = core_.estimate(robot);
    pacer_.sent(robot, e ? e->poses.size() : 0, now);
    if (!e) continue;
    publish_result(*e);
    log_result(core_.version(), *e);
  }
}

// Where the central is in W: fixed, or its host robot's newest keyframe; nullopt while the host
// robot is not in the world (a restarted central knows no world until the host's poses arrive).
std::optional<Eigen::Vector3d> CentralNode::position() const {
  if (o_.central_on_robot < 0) return o_.central_position;
  return core_.newest_position(static_cast<uint32_t>(o_.central_on_robot));
}

void CentralNode::publish_result(const RobotEstimate& e) {
  pose_storage_.clear();
  for (const auto& [id, T] : e.poses) pose_storage_.push_back(cdc_msg_KeyframePose{e.robot, id, dds::to_msg(T)});
  cdc_msg_OptimizedPoses msg{};
  msg.robot_id = e.robot;
  msg.sender_robot_id = o_.central_id;
  msg.sender_incarnation = incarnation_;
  msg.graph_version = core_.version();
  msg.stamp_ns = dds::now_ns();
  msg.source = e.from_hint ? cdc_msg_SOURCE_CENTRAL_HINT : cdc_msg_SOURCE_CENTRAL;
  msg.T_world_robot = dds::to_msg(e.T_world_robot);
  dds::borrow(msg.poses, pose_storage_);
  w_results_.at(e.robot).write(msg);
}

void CentralNode::publish_acknowledgements() {
  for (const Acknowledgement& a : core_.acknowledgements()) {
    cdc_msg_Acknowledgement m{};
    m.robot_id = a.robot;
    m.robot_incarnation = a.incarnation;
    m.central_incarnation = incarnation_;
    m.stamp_ns = dds::now_ns();
    m.highest_contiguous_keyframe = a.highest_contiguous_keyframe;
    m.highest_contiguous_loop_seq = a.highest_contiguous_loop_seq;
    w_ack_.write(m);
  }
  acks_dirty_ = false;
}

void CentralNode::publish_status() {
  cdc_msg_RobotStatus s{};
  s.robot_id = o_.central_id;
  s.incarnation = incarnation_;
  s.stamp_ns = dds::now_ns();
  const std::optional<Eigen::Vector3d> p = position();
  s.world_valid = p.has_value();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (p) T.translation() = *p;
  s.T_world_base = dds::to_msg(T);
  s.last_keyframe_id = -1;
  s.mode = cdc_msg_MODE_CENTRALIZED;
  s.is_central = true;
  w_status_.write(s);
  w_alive_.write(s);
}

// The wall time of the most recent updates (at most kUpdateTimesKept), for the stats.
void CentralNode::record_update_time(double ms) {
  if (update_ms_.size() < kUpdateTimesKept) {
    update_ms_.push_back(ms);
  } else {
    update_ms_[schedule_.updates() % kUpdateTimesKept] = ms;
  }
}

// Samples the DDS readers lost or refused (what never reached the boundary), by input.
nlohmann::json CentralNode::reader_losses() const {
  nlohmann::json j;
  const auto add = [&j](const std::string& name, const dds::ReaderLosses& l) {
    j[name] = {{"lost", l.lost}, {"rejected", l.rejected}};
  };
  add("keyframes", keyframes_.reader().losses());
  add("loops", loops_.reader().losses());
  add("world", world_.reader().losses());
  return j;
}

nlohmann::json CentralNode::update_times() const {
  const geometry::ErrorStats t = geometry::compute_stats(update_ms_);
  return {{"recent", t.count}, {"median", t.median}, {"p90", t.p90}, {"max", t.max}};
}

nlohmann::json CentralNode::stats(double final_cost) const {
  nlohmann::json j = core_.counters();
  j.update({{"incarnation", incarnation_},
            {"keyframes_pending", core_.keyframes_pending()},
            {"max_pending_keyframes", o_.core.max_pending_keyframes},
            {"reader_losses", reader_losses()},
            {"update_ms", update_times()},
            {"graph_poses", core_.graph().poses.size()},
            {"graph_factors", core_.graph().factors.size()},
            {"updates", schedule_.updates()},
            {"unsettled_updates", schedule_.unsettled_updates()},
            {"results_held", schedule_.results_held()},
            {"results_merged", pacer_.merged()},
            {"final_cost", final_cost}});
  nlohmann::json sessions = nlohmann::json::array();
  for (const Acknowledgement& a : core_.acknowledgements()) {
    sessions.push_back({{"robot", a.robot},
                        {"incarnation", a.incarnation},
                        {"highest_contiguous_keyframe", a.highest_contiguous_keyframe},
                        {"highest_contiguous_loop_seq", a.highest_contiguous_loop_seq},
                        {"keyframes_held", core_.keyframes_held(a.robot, a.incarnation)}});
  }
  j["sessions"] = sessions;
  return j;
}

void CentralNode::finish() {
  spdlog::info("shutting down (signal {}): final optimisation", dds::ShutdownSignal::signal_number());
  const UpdateStats final_stats = core_.optimise_fully();
  if (!o_.graph_out.empty()) graph::write_g2o(o_.graph_out, core_.graph());
  runtime::write_stats(service_, stats(final_stats.cost));
}

}  // namespace cdc::central
