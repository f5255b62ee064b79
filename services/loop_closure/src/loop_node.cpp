#include "loop_node.hpp"

#include "loop_messages.hpp"

#include "cdc/dds/compact.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/runtime/stats.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>
#include <string>
#include <utility>

namespace cdc::loops {
namespace {

namespace topics = dds::topics;
namespace qos = dds::qos;
namespace partitions = dds::partitions;

}  // namespace

// The robot's own domain carries its keyframes, its own descriptors and a copy of its loop closures.
LoopNode::LoopNode(const runtime::ServiceOptions& common, const LoopNodeOptions& o)
    : o_(o),
      t0_(std::chrono::steady_clock::now()),
      service_(runtime::Domains::kRobot, common, runtime::swarm_limits(o.robots)),
      // Peers' status is taken on every pass: no reason to wake up for it.
      status_(service_, service_.radio(), topics::kRobotStatus, qos::keyed_state(), false),
      requests_(service_, service_.radio(), topics::kCloudRequest, qos::event_stream(256)),
      keyframes_(service_, service_.secondary(), topics::kKeyframe,
                 qos::event_stream(4096).partitions(partitions::own_reader(common.robot))),
      descriptors_(service_, service_.radio(), topics::kDescriptor, qos::event_stream(1024)),
      descriptors_resent_(service_, service_.radio(), topics::kDescriptor,
                          qos::event_stream(1024).partitions({partitions::robot(common.robot)})),
      replies_(service_, service_.radio(), topics::kCloudReply,
               qos::event_stream(256).partitions(partitions::own_reader(common.robot))),
      t_rep_(service_.radio(), topics::kCloudReply),
      w_loop_(service_.radio(), topics::kLoopClosure,
              qos::event_stream(4096).partitions({partitions::robot(common.robot)})),
      w_loop_with_(service_.radio(), w_loop_.topic(), qos::event_stream(4096), o.robots, common.robot,
                   {partitions::robot(common.robot)}),
      w_req_(service_.radio(), topics::kCloudRequest, qos::event_stream(256)),
      w_rep_to_(service_.radio(), t_rep_, qos::event_stream(256), o.robots, common.robot),
      w_sync_(service_.radio(), topics::kDescriptorSync, qos::event_stream(256)),
      core_(o.core, common.robot),
      sequencer_(o.sequencer),
      reach_(common.robot, o.reach),
      written_(reach_),
      numbering_(o.state_file),
      backlog_file_(o.backlog_out) {
  // With a local domain of its own, the robot's own descriptors come in there and its loop closures
  // go out there too (to its peer optimiser), also while the radio is cut; the radio then brings
  // only the peers' descriptors.
  if (service_.split()) {
    descriptors_local_.emplace(service_, service_.secondary(), topics::kDescriptor, qos::event_stream(1024));
    w_loop_local_.emplace(service_.secondary(), topics::kLoopClosure, qos::event_stream(4096));
  }
  wire_inputs();
  core_.set_reachable([this](uint32_t robot) { return in_reach(robot); });
  log_start();
}

// Each input: which samples are this robot's to take, the check of its own after dds::validate, and
// its handler.
void LoopNode::wire_inputs() {
  const uint32_t me = service_.options().robot;
  status_.filter([me](const cdc_msg_RobotStatus& m) { return m.robot_id != me && !m.is_central; })
      .on([this](const cdc_msg_RobotStatus& m) { on_status(m); });
  requests_.filter([me](const cdc_msg_CloudRequest& m) { return m.owner_robot_id == me; })
      .on([this](const cdc_msg_CloudRequest& m) { on_cloud_request(m); });
  keyframes_.filter([me](const cdc_msg_Keyframe& m) { return m.robot_id == me; }).on([this](const cdc_msg_Keyframe& m) {
    on_keyframe(m);
  });
  // Descriptors arrive live (volatile), and those missed on request: a gap in a robot's keyframe ids
  // is asked for on cdc/place/descriptor_sync and the owner's descriptor service sends just that
  // range again, in this robot's partition (also the robot's own).
  const auto shape = [this](const cdc_msg_Descriptor& m) { return check_descriptor_shape(m, o_.core.scan_context); };
  const auto take = [this](const cdc_msg_Descriptor& m) { on_descriptor(m); };
  descriptors_resent_.check(shape).on(take);
  descriptors_.check(shape).on(take);
  if (descriptors_local_) {
    // The robot's own live descriptors come on the local domain; their radio copies are dropped
    // before any work.
    descriptors_.filter([me](const cdc_msg_Descriptor& m) { return m.robot_id != me; });
    descriptors_local_->filter([me](const cdc_msg_Descriptor& m) { return m.robot_id == me; }).check(shape).on(take);
  }
  replies_.filter([me](const cdc_msg_CloudReply& m) { return m.requester_robot_id == me; })
      .on([this](const cdc_msg_CloudReply& m) { on_cloud_reply(m); });
}

void LoopNode::log_start() const {
  if (!numbering_.last_error().empty()) {
    spdlog::error("{}", numbering_.last_error());
  } else if (const auto st = numbering_.stored()) {
    spdlog::info("loop numbering state {}: incarnation {}, next loop {}", o_.state_file, st->first, st->second);
  }
  spdlog::info("loop-closure service of robot {} up: {} robots, PCM chi2 {}, domain {}{}", service_.options().robot,
               o_.robots, o_.core.pcm.chi2_threshold, service_.options().domain_id(),
               service_.split() ? ", own keyframes, descriptors and loops on local domain " +
                                      std::to_string(service_.options().local_domain)
                                : std::string());
}

void LoopNode::spin() {
  while (service_.wait(std::chrono::milliseconds(to_search_.empty() ? o_.tick_ms : 0))) {
    now_ = clock();
    status_.poll(64);
    // Peers' cloud requests before descriptors: serving one is cheap, and a requester gives up after
    // its timeout (descriptor bursts after a reconnection can take seconds to search and verify).
    requests_.poll(64);
    keyframes_.poll(64);
    poll_descriptors();
    ask_for_missed_descriptors();
    search_next();
    replies_.poll(1);
    handle(core_.tick(clock()));
    backlog_file_.update(backlog());
    write_loops_again();
  }
}

// Peers' periodic status (their peer optimisers'): a peer that makes no keyframes (stopped, or at the
// end of a mission) is still heard through it, so that the clouds parked for it are asked for.
void LoopNode::on_status(const cdc_msg_RobotStatus& m) {
  traffic_.received(m.robot_id, dds::serialized_size(m));
  reach_.heard(m.robot_id, clock());
  // Its last keyframe: descriptors it made out of range just before it stopped making keyframes have
  // nothing after them to show the gap; the sequencer asks for them from this mark.
  if (m.last_keyframe_id >= 0 && m.last_keyframe_id <= std::numeric_limits<uint32_t>::max()) {
    sequencer_.announce(m.robot_id, static_cast<uint32_t>(m.last_keyframe_id), now_);
  }
}

void LoopNode::on_cloud_request(const cdc_msg_CloudRequest& m) {
  traffic_.received(m.requester_robot_id, dds::serialized_size(m));
  reach_.heard(m.requester_robot_id, clock());
  const std::vector<Eigen::Vector3f>* cloud = core_.cloud(service_.options().robot, m.keyframe_id);
  dds::compact::PackedCloud packed;
  packed.resolution_m = o_.reply_resolution_m;
  if (cloud != nullptr) {
    packed = dds::compact::pack_points(*cloud, o_.reply_resolution_m);
    ++counters_.requests_served;
    counters_.points_served += packed.count;
  } else {
    ++counters_.requests_unknown_keyframe;
  }
  // Cloud replies go only to the robot that asked.
  dds::Writer<cdc_msg_CloudReply>* to = w_rep_to_.to(m.requester_robot_id);
  if (to == nullptr) return;  // not a peer (the requester id is validated)
  const cdc_msg_CloudReply reply = cloud_reply(m, service_.options().robot, incarnation_, cloud != nullptr, packed);
  to->write(reply);
  traffic_.sent(m.requester_robot_id, dds::serialized_size(reply));
  spdlog::debug("served cloud {}/{} to robot {}: {} points in {} B, request {} ms old", service_.options().robot,
                m.keyframe_id, m.requester_robot_id, packed.count, packed.bytes.size(),
                (dds::now_ns() - m.stamp_ns) / 1'000'000);
}

void LoopNode::on_keyframe(const cdc_msg_Keyframe& m) {
  incarnation_ = m.incarnation;
  handle(core_.add_keyframe_data(keyframe_in(m), now_));
}

// The sequencer holds back what came after a gap until it is filled, so that every robot's
// descriptors are searched in keyframe order.
void LoopNode::on_descriptor(const cdc_msg_Descriptor& m) {
  if (m.robot_id != service_.options().robot) {
    traffic_.received(m.robot_id, dds::serialized_size(m));
    reach_.heard(m.robot_id, clock());
  }
  for (DescriptorIn& d : sequencer_.add(descriptor_in(m))) to_search_.push(std::move(d), clock());
}

void LoopNode::on_cloud_reply(const cdc_msg_CloudReply& m) {
  traffic_.received(m.owner_robot_id, dds::serialized_size(m));
  // What the reply is to the core: answered is what it still waits for (pending, or parked to be asked
  // again: a late answer to an earlier attempt is as good as the awaited one); the request id is informational.
  switch (core_.reply_use(m.owner_robot_id, m.keyframe_id, m.found)) {
    case ReplyUse::kCloud:
      handle(core_.on_cloud(m.owner_robot_id, m.keyframe_id, reply_cloud(m), now_));
      break;
    case ReplyUse::kNotHeld:
      core_.on_cloud_missing(m.owner_robot_id, m.keyframe_id, clock());
      break;
    case ReplyUse::kDuplicate:
      ++counters_.cloud_replies_duplicate;
      break;
    case ReplyUse::kUnrequested:
      service_.boundary().refuse(topics::kCloudReply,
                                 dds::Validation::fail("keyframe_id: answers no open request of this robot"));
      break;
  }
}

// Descriptors enter the sequencer as they arrive, so that a gap being filled shows at once: an answer
// left waiting behind a burst of verifications would look like no answer, and the gap would be asked
// for again.
void LoopNode::poll_descriptors() {
  descriptors_resent_.poll(256);
  descriptors_.poll(256);
  if (descriptors_local_) descriptors_local_->poll(256);
}

void LoopNode::ask_for_missed_descriptors() {
  std::vector<DescriptorIn> released;  // held behind a gap given up
  for (const SyncWanted& w : sequencer_.wanted(
           now_, [this](uint32_t robot) { return in_reach(robot); }, released)) {
    const cdc_msg_DescriptorSync q = descriptor_sync(w, service_.options().robot);
    w_sync_.write(q);
    traffic_.sent(w.robot, dds::serialized_size(q));
    spdlog::debug("asked robot {} for its descriptors {}..{}", w.robot, w.first, w.last);
  }
  for (DescriptorIn& d : released) to_search_.push(std::move(d), now_);
}

// One descriptor (and one cloud reply) searched per pass: each can start registrations, and between
// them peers' cloud requests and this robot's own keyframes must not wait (a burst of descriptors
// after a reconnection takes many seconds to search and verify).
void LoopNode::search_next() {
  counters_.descriptors_waiting_peak = std::max<uint64_t>(counters_.descriptors_waiting_peak, to_search_.size());
  if (auto d = to_search_.pop()) handle(core_.add_descriptor(std::move(*d), now_));
}

void LoopNode::handle(LoopEvents events) {
  request_clouds(events.requests);
  for (const Verification& v : events.verifications) {
    spdlog::debug(
        "verified {}/{} against {}/{}: {}, fitness {:.3f} m^2, overlap {:.2f}, guess {:.1f} m, moved {:.2f} m",
        v.query_robot, v.query_id, v.candidate_robot, v.candidate_id,
        v.passed ? "passed" : (v.converged ? "failed" : "not converged"), v.fitness, v.overlap, v.guess_m,
        v.correction_m);
  }
  for (const LoopOut& l : events.loops) publish(l);
}

void LoopNode::request_clouds(const std::vector<CloudWanted>& wanted) {
  for (const CloudWanted& c : wanted) {
    const cdc_msg_CloudRequest q = cloud_request(c, service_.options().robot, incarnation_, next_request_++);
    w_req_.write(q);
    spdlog::debug("requested cloud {}/{} (request {})", c.robot, c.id, q.request_id);
    traffic_.sent(c.robot, dds::serialized_size(q));
  }
}

void LoopNode::publish(const LoopOut& l) {
  const cdc_msg_LoopClosure m = loop_message(l, service_.options().robot, incarnation_, next_loop_seq());
  write_loop(m);
  if (w_loop_local_) w_loop_local_->write(m);
  ++counters_.loops_published;
  if (!l.withdrawn) {
    if (const auto latency = to_search_.latency_s(l, clock())) latencies_s_.push_back(*latency);
  }
  written_.wrote(m, l.withdrawn, clock());
  spdlog::info("{} loop {}/{} - {}/{} (fitness {:.3f})", l.withdrawn ? "withdrew" : "published", l.robot_a,
               l.keyframe_a, l.robot_b, l.keyframe_b, l.fitness);
}

// Loops go only where they are needed: an own-robot loop in this robot's partition (its peer
// optimiser, the central), a loop with peer r in both robots' partitions; never to a third robot.
void LoopNode::write_loop(const cdc_msg_LoopClosure& m) {
  const uint32_t other = m.robot_a == service_.options().robot ? m.robot_b : m.robot_a;
  dds::Writer<cdc_msg_LoopClosure>* to = w_loop_with_.to(other);
  (to != nullptr ? *to : w_loop_).write(m);
}

// A peer heard again after a silence gets the loops involving it that it may have missed meanwhile.
void LoopNode::write_loops_again() {
  const std::vector<const cdc_msg_LoopClosure*> again = written_.due(clock());
  if (again.empty()) return;
  for (const cdc_msg_LoopClosure* m : again) write_loop(*m);
  spdlog::info("wrote {} loops again (loops {}..{}) for a peer heard again after a silence", again.size(),
               again.front()->loop_seq, again.back()->loop_seq);
}

// Loop numbers per incarnation, kept in the state file across restarts of this service alone.
uint32_t LoopNode::next_loop_seq() {
  const uint64_t resumed = numbering_.stats().resumed;
  const uint32_t seq = numbering_.take(incarnation_);
  if (numbering_.stats().resumed != resumed) {
    spdlog::info("incarnation {} as before the restart: loop numbers go on from {}", incarnation_, seq);
  }
  if (const uint64_t f = numbering_.stats().save_failures; f != numbering_failures_logged_) {
    numbering_failures_logged_ = f;
    if (f == 1 || f % 100 == 0) {  // the first, then every hundredth: a read-only disk fails every loop
      spdlog::error("{} (failure {}; loops are still written)", numbering_.last_error(), f);
    }
  }
  return seq;
}

Backlog LoopNode::backlog() const {
  return {to_search_.size() + sequencer_.missing(), core_.pending_requests(), core_.parked_requests(),
          counters_.loops_published};
}

Nanos LoopNode::clock() const { return std::chrono::duration_cast<Nanos>(std::chrono::steady_clock::now() - t0_); }

// This robot's own services always; a peer while heard within the reach's silence.
bool LoopNode::in_reach(uint32_t robot) const { return reach_.in_reach(robot, clock()); }

nlohmann::json LoopNode::stats() const {
  nlohmann::json j = core_counters(core_.stats());
  j.update(nlohmann::json(counters_));
  j.update(nlohmann::json(sequencer_counters(sequencer_.stats())));
  j.update(nlohmann::json(reach_counters(reach_.stats())));
  j["robot"] = service_.options().robot;
  j["keyframes"] = core_.keyframes();
  j["loop_numbering"] = numbering_counters(numbering_.stats(), o_.state_file);
  j["loop_latency_s"] = latency_summary(latencies_s_);
  j["bytes_per_peer"] = traffic_.by_peer();
  j["radio_cuts"] = service_.robot_domains()->radio_cuts();
  return j;
}

void LoopNode::finish() const {
  runtime::write_stats(service_, stats());
  spdlog::info("stopped: {} loop messages, {} rejected samples", counters_.loops_published,
               service_.boundary().rejected().total());
}

}  // namespace cdc::loops
