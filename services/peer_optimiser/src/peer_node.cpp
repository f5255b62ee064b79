#include "peer_node.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/runtime/logging.hpp"
#include "cdc/runtime/stats.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>

namespace cdc::peer {

// Counters and state as --stats-out names them.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(PeerNodeCounters, forwarded_keyframes, withheld_keyframes, keyframe_writer_discards,
                                   resent_keyframes, resent_loops, forwarded_cloud_bytes, resent_cloud_bytes,
                                   cloud_points_dropped, corrections, separator_messages)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(PeerNodeState, robot, mode, transitions, keyframes, keyframes_duplicate,
                                   keyframes_refused, distributed_rounds, radio_cuts, coarse_steps, own_loops_held_out,
                                   separator_poses, relayed_loops)

namespace {

namespace topics = dds::topics;
namespace qos = dds::qos;
namespace partitions = dds::partitions;

}  // namespace

// The robot's own keyframes and loop closures, and its corrections, travel on its local domain when
// it has one (see cdc/dds/robot_domains.hpp); the node then forwards keyframes to the central over
// the radio without their clouds, each cloud packed beside it for the central's map, and takes loop
// closures from both domains (each counted once by the core).
PeerNode::PeerNode(const runtime::ServiceOptions& common, const PeerNodeOptions& o)
    : o_(o),
      service_(runtime::Domains::kRobot, common, runtime::swarm_limits(o.core.robot_count, {o.central_id})),
      keyframes_(service_, service_.secondary(), topics::kKeyframe,
                 qos::event_stream(4096).partitions(partitions::own_reader(o.core.robot))),
      loops_(service_, service_.radio(), topics::kLoopClosure,
             qos::event_stream(4096).partitions(partitions::own_reader(o.core.robot))),
      // The central's results for this robot only (its partition); its liveliness is watched below.
      central_results_(service_, service_.radio(), topics::kCentralOptimized,
                       qos::monitored_reader().partitions({partitions::robot(o.core.robot)})),
      acks_(service_, service_.radio(), topics::kCentralAck, qos::keyed_state(), false),
      separators_(service_, service_.radio(), topics::kSeparator,
                  qos::event_stream(256).partitions(partitions::own_reader(o.core.robot))),
      statuses_(service_, service_.radio(), topics::kRobotStatus, qos::keyed_state(), false),
      t_sep_(service_.radio(), topics::kSeparator),
      t_alive_(service_.radio(), topics::kCentralAlive),
      w_mode_(service_.radio(), topics::kMode, qos::keyed_state(8)),
      w_corr_(service_.secondary(), topics::kCorrection,
              qos::event_stream(64).partitions({partitions::robot(o.core.robot)})),
      // Separators go only to the peer they are for (each crosses only the link to it).
      w_sep_(service_.radio(), t_sep_, qos::event_stream(256), o.core.robot_count, o.core.robot),
      w_world_(service_.radio(), topics::kWorldTransform, qos::keyed_state()),
      // Where the keyframe sequence stands, kept for a front-end that (re)starts (transient-local).
      w_sequence_(service_.secondary(), topics::kKeyframeSequence,
                  qos::keyed_state().partitions({partitions::robot(o.core.robot)})),
      w_kf_(service_.radio(), topics::kKeyframe, qos::event_stream(4096).partitions({partitions::robot(o.core.robot)})),
      w_cloud_(service_.radio(), topics::kKeyframeCloud,
               qos::event_stream(4096).partitions({partitions::robot(o.core.robot)})),
      // Own loops re-sent for the central: in the robot's partition, so that they do not cross to peers.
      w_loop_(service_.radio(), topics::kLoopClosure,
              qos::event_stream(4096).partitions({partitions::robot(o.core.robot)})),
      w_status_(service_.radio(), topics::kRobotStatus, qos::keyed_state()),
      central_(service_.radio(), t_alive_.handle(), "central optimiser"),
      core_(o.core, elapsed()),
      mode_files_(o.mode_out),
      separator_matches_(o.core.robot_count, 0),
      mode_period_(std::chrono::milliseconds(o.mode_period_ms)),
      radio_status_period_(std::chrono::milliseconds(o.radio_status_period_ms)),
      status_file_period_(std::chrono::milliseconds(o.status_period_ms)) {
  if (service_.split())
    local_loops_.emplace(service_, service_.secondary(), topics::kLoopClosure, qos::event_stream(4096));
  wire_inputs();
  w_sequence_.write(keyframe_sequence(o.core.robot, nullptr));
  central_.set_notify(&liveliness_changed_);
  service_.watch(liveliness_changed_);
  spdlog::info("peer optimiser of robot {} up: CR_0 {} m, dwell {} ms, mask {} ms, domain {}{}", o.core.robot,
               o.core.rtdos.range_m, o.core.rtdos.dwell.count() / 1'000'000, o.core.rtdos.mask.count() / 1'000'000,
               common.domain_id(),
               service_.split()
                   ? ", own keyframes, loops and corrections on local domain " + std::to_string(common.local_domain)
                   : std::string());
}

// Each input takes only what is for this robot, and hands it to its on_<topic>().
void PeerNode::wire_inputs() {
  const uint32_t me = o_.core.robot;
  keyframes_.filter([me](const cdc_msg_Keyframe& m) { return m.robot_id == me; }).on([this](const cdc_msg_Keyframe& m) {
    on_keyframe(m);
  });
  auto wire_loops = [&](runtime::Input<cdc_msg_LoopClosure>& loops) {
    loops.filter([me](const cdc_msg_LoopClosure& m) { return m.robot_a == me || m.robot_b == me; })
        .on([this](const cdc_msg_LoopClosure& m) { on_loop(m); });
  };
  wire_loops(loops_);
  if (local_loops_) wire_loops(*local_loops_);
  central_results_.filter([me](const cdc_msg_OptimizedPoses& m) { return m.robot_id == me; })
      .on([this](const cdc_msg_OptimizedPoses& m) { on_central_result(m); });
  acks_.filter([me](const cdc_msg_Acknowledgement& m) { return m.robot_id == me; })
      .on([this](const cdc_msg_Acknowledgement& m) { on_ack(m); });
  separators_.filter([me](const cdc_msg_SeparatorPoses& m) { return m.target_robot_id == me; })
      .on([this](const cdc_msg_SeparatorPoses& m) { on_separator(m); });
  statuses_.filter([me](const cdc_msg_RobotStatus& m) { return m.robot_id != me; })
      .on([this](const cdc_msg_RobotStatus& m) { on_status(m); });
}

PeerNode::~PeerNode() { central_.set_notify(nullptr); }

void PeerNode::spin() {
  while (service_.wait(std::chrono::milliseconds(o_.tick_ms))) {
    liveliness_changed_.reset();
    now_ = elapsed();
    take_inputs();
    notice_rematched_peers();
    step();
  }
}

void PeerNode::take_inputs() {
  keyframes_.poll(1024);
  loops_.poll(1024);
  if (local_loops_) local_loops_->poll(1024);
  central_results_.poll(64);
  acks_.poll(64);
  separators_.poll(256);
  statuses_.poll(64);
}

// The core decides whether the keyframe joins the robot's sequence; only then does the node keep its
// cloud (packed), tell a restarting front-end where the sequence stands, and forward it.
void PeerNode::on_keyframe(const cdc_msg_Keyframe& m) {
  const OwnKeyframe k = own_keyframe(m);
  const KeyframeAdmission a = core_.add_keyframe(k, now_);
  if (a.outcome == Admission::kRefused) service_.boundary().refuse(topics::kKeyframe, dds::Validation::fail(a.reason));
  if (a.outcome != Admission::kAccepted) return;
  incarnation_ = m.incarnation;
  sim_stamp_ns_ = std::max(sim_stamp_ns_, m.stamp_ns);
  dds::compact::PackedCloud& packed = records_.keep_cloud(m, o_.map_cloud_resolution_m);
  counters_.cloud_points_dropped += packed.dropped;
  w_sequence_.write(keyframe_sequence(o_.core.robot, core_.newest_keyframe()));
  // The central (and its map) read keyframes on the SLAM domain. Only a CENTRALIZED robot sends
  // them: a DISTRIBUTED one exchanges descriptors and separators only, and its keyframes reach the
  // central as the backlog it re-sends on rejoining (all the central has not acknowledged). Without a
  // local domain the front-end's keyframes reach the central themselves: only the cloud goes.
  if (!core_.forwards_keyframes()) {
    ++counters_.withheld_keyframes;
    return;
  }
  counters_.forwarded_cloud_bytes += send_keyframe(k, packed, service_.split());
  ++counters_.forwarded_keyframes;
}

// The keyframe for the central without its cloud (with_keyframe), and its packed cloud for the map.
// Returns the packed cloud's bytes.
uint64_t PeerNode::send_keyframe(const OwnKeyframe& k, dds::compact::PackedCloud& packed, bool with_keyframe) {
  if (with_keyframe) w_kf_.write(keyframe_message(o_.core.robot, k));
  w_cloud_.write(keyframe_cloud_message(o_.core.robot, k, packed));
  return packed.bytes.size();
}

void PeerNode::on_loop(const cdc_msg_LoopClosure& m) {
  if (m.sender_robot_id == o_.core.robot) records_.keep(m);
  core_.add_loop(loop_record(m), now_);
}

void PeerNode::on_central_result(const cdc_msg_OptimizedPoses& m) { core_.on_central_result(central_result(m)); }

void PeerNode::on_ack(const cdc_msg_Acknowledgement& m) { core_.on_ack(ack_in(m)); }

void PeerNode::on_separator(const cdc_msg_SeparatorPoses& m) { core_.on_separator(m.robot_id, separator_in(m)); }

void PeerNode::on_status(const cdc_msg_RobotStatus& m) {
  if (!m.is_central) core_.on_peer_mode(m.robot_id, from_msg(m.mode));
  const std::optional<Eigen::Vector3d> p = status_position(m);
  if (m.is_central) {
    core_.on_central_position(p);  // no world: the distance is unknown (in range), not from the origin
  } else if (p) {
    core_.on_peer_position(m.robot_id, *p);
  }
}

// A peer's reader matched anew (it came back in reach after its lease lapsed, or restarted) has
// missed the separators written while it was away: it gets all of them next round.
void PeerNode::notice_rematched_peers() {
  for (uint32_t r = 0; r < w_sep_.size(); ++r) {
    const dds::Writer<cdc_msg_SeparatorPoses>* w = w_sep_.to(r);
    if (w == nullptr) continue;
    const uint32_t matched = w->readers_ever_matched();
    if (matched == separator_matches_[r]) continue;
    separator_matches_[r] = matched;
    core_.resend_separators_to(r);
  }
}

void PeerNode::step() {
  const bool alive = central_.state() == dds::Liveliness::kAlive;
  const StepOutput out = core_.step(now_, alive);
  if (out.transition) {
    on_transition(*out.transition, alive, out.drop_undelivered_keyframes);
  } else if (mode_period_.due(Clock::now())) {
    publish_mode(core_.rtdos().last_reason(), core_.distance_to_central());
    mode_period_.done(Clock::now());
  }
  if (out.world_transform) {
    w_world_.write(world_transform(origin(), *out.world_transform, core_.distributed_rounds()));
  }
  resend(out);
  publish_separators(out.separators);
  if (out.correction) publish_correction(*out.correction);
  publish_status(alive);
}

void PeerNode::on_transition(const Transition& t, bool central_alive, bool drop_undelivered_keyframes) {
  spdlog::info("mode {} -> {} ({}), distance to central {}", to_string(t.from), to_string(t.to), to_string(t.reason),
               t.distance_m ? std::to_string(*t.distance_m) + " m" : "unknown");
  publish_mode(t.reason, t.distance_m);
  mode_period_.done(Clock::now());
  radio_status_period_.expire();  // peers learn the new mode at once (separators follow it)
  write_now(central_alive);
  if (drop_undelivered_keyframes && service_.split()) {
    // Keyframes forwarded since the link to the central was cut (until its lease lapsed) are
    // unacknowledged: dropped here, they reach the central as the backlog re-sent on rejoining,
    // not by DDS as soon as the link returns while this robot is still DISTRIBUTED.
    w_kf_.discard_unacknowledged();
    w_cloud_.discard_unacknowledged();
    ++counters_.keyframe_writer_discards;
  }
  mode_files_.transition(t, dds::now_ns(), sim_stamp_ns_, o_.core.robot, core_.keyframes_held());
}

// distance: the one the switch was decided on (the estimate can move within the same step).
void PeerNode::publish_mode(SwitchReason reason, std::optional<double> distance) {
  w_mode_.write(mode_state(origin(), core_.mode(), reason, distance, core_.rtdos().transitions()));
}

void PeerNode::resend(const StepOutput& out) {
  for (uint32_t id : out.resend_keyframes) {
    const OwnKeyframe* k = core_.keyframe(id);
    dds::compact::PackedCloud* cloud = records_.cloud(id);
    if (k == nullptr || cloud == nullptr) continue;
    counters_.resent_cloud_bytes += send_keyframe(*k, *cloud, true);
    ++counters_.resent_keyframes;
  }
  for (uint32_t seq : out.resend_loops) {
    if (const cdc_msg_LoopClosure* m = records_.loop(seq)) {
      w_loop_.write(*m);
      ++counters_.resent_loops;
    }
  }
  if (!out.resend_keyframes.empty() || !out.resend_loops.empty()) {
    spdlog::info("re-sent {} keyframes and {} loop closures the central had not acknowledged",
                 out.resend_keyframes.size(), out.resend_loops.size());
  }
}

void PeerNode::publish_separators(const std::vector<SeparatorOut>& separators) {
  for (const SeparatorOut& s : separators) {
    dds::Writer<cdc_msg_SeparatorPoses>* to = w_sep_.to(s.target);
    if (to == nullptr) continue;  // targets are robots of validated loops, never this robot
    to->write(separator_message(origin(), s, static_cast<uint32_t>(core_.distributed_rounds()), separator_storage_));
    ++counters_.separator_messages;
  }
}

void PeerNode::publish_correction(const Correction& c) {
  w_corr_.write(correction_message(origin(), c, counters_.corrections, pose_storage_));
  ++counters_.corrections;
  if (spdlog::should_log(spdlog::level::debug) && !c.poses.empty()) log_correction(c);
}

// What the front-end takes.
void PeerNode::log_correction(const Correction& c) const {
  spdlog::debug("correction {} ({}, lambda {:.3f}): {}", counters_.corrections,
                c.from_central ? "central" : "distributed", c.lambda,
                runtime::world_estimate_text(c.T_world_robot, c.poses.back().first, c.poses.back().second));
}

// The robot's status on the radio every radio_status_period_ms, the launcher's file every status_period_ms.
void PeerNode::publish_status(bool central_alive) {
  if (radio_status_period_.due(Clock::now())) {
    w_status_.write(robot_status(origin(), core_.world_pose(), core_.last_keyframe_id(), core_.mode()));
    radio_status_period_.done(Clock::now());
  }
  if (status_file_period_.due(Clock::now())) {
    status_file_period_.done(Clock::now());
    write_now(central_alive);
  }
}

void PeerNode::write_now(bool central_alive) const {
  mode_files_.now(BackendState{core_.mode(), core_.keyframes_held(), core_.rtdos().transitions(), central_alive,
                               core_.central_acknowledged_keyframe()});
}

Origin PeerNode::origin() const { return Origin{o_.core.robot, incarnation_, dds::now_ns()}; }

nlohmann::json PeerNode::stats() const {
  PeerNodeState state;
  state.robot = o_.core.robot;
  state.mode = to_string(core_.mode());
  state.transitions = core_.rtdos().transitions();
  state.keyframes = core_.keyframes_held();
  state.keyframes_duplicate = core_.keyframe_counters().duplicate;
  state.keyframes_refused = core_.keyframe_counters().refused;
  state.distributed_rounds = core_.distributed_rounds();
  state.coarse_steps = core_.coarse_steps();
  state.own_loops_held_out = core_.own_loops_held_out();
  state.separator_poses = core_.separator_traffic().poses;
  state.relayed_loops = core_.separator_traffic().loops;
  state.radio_cuts = service_.robot_domains()->radio_cuts();
  nlohmann::json j = state;
  j.update(nlohmann::json(counters_));
  return j;
}

void PeerNode::finish() const {
  if (!o_.trajectory_out.empty()) geometry::write_tum(o_.trajectory_out, core_.world_trajectory());
  if (!o_.graph_out.empty()) graph::write_g2o(o_.graph_out, core_.graph());
  runtime::write_stats(service_, stats());
  spdlog::info("stopped (signal {})", dds::ShutdownSignal::signal_number());
}

}  // namespace cdc::peer
