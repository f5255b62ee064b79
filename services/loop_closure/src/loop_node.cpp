#include "loop_node.hpp"

#include "cdc/loop_closure/loop_numbering.hpp"
#include "cdc/loop_closure/peer_reach.hpp"
#include "cdc/loop_closure/search_queue.hpp"

#include "cdc/dds/compact.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/traffic_json.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/dds_lidar/descriptor_convert.hpp"
#include "cdc/runtime/logging.hpp"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cstdio>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <optional>

namespace cdc::loops {
namespace {

using Clock = std::chrono::steady_clock;
namespace topics = dds::topics;

// Bytes exchanged with each peer robot (its serialised samples); per-topic totals are counted
// by the DDS layer (cdc/dds/traffic.hpp).
struct PeerTraffic {
  std::map<uint32_t, std::pair<uint64_t, uint64_t>> peer;  // robot -> (sent to, received from)
  void out(size_t bytes, uint32_t to) { peer[to].first += bytes; }
  void in(size_t bytes, uint32_t from) { peer[from].second += bytes; }
};

}  // namespace

int run_loop_closure(const LoopNodeOptions& o) {
  const uint32_t me = o.robot;
  dds::ParticipantOptions po;
  po.domain_id = o.domain;
  po.config = o.dds_config;
  dds::RobotDomains domains(po, dds::local_domain_options(o.local_domain, o.local_dds_config, po), runtime::log_radio_switch);
  const dds::Participant& participant = domains.radio();
  const dds::Participant& local = domains.local();
  dds::Topic<cdc_msg_Keyframe> t_kf(local, topics::kKeyframe);
  dds::Topic<cdc_msg_Descriptor> t_desc(participant, topics::kDescriptor);
  dds::Topic<cdc_msg_LoopClosure> t_loop(participant, topics::kLoopClosure);
  dds::Topic<cdc_msg_CloudRequest> t_req(participant, topics::kCloudRequest);
  dds::Topic<cdc_msg_CloudReply> t_rep(participant, topics::kCloudReply);
  dds::Reader<cdc_msg_Keyframe> r_kf(local, t_kf, dds::qos::event_stream(4096).partitions(dds::partitions::own_reader(me)));
  // With a local domain of its own, the robot's own descriptors come in there and its loop closures
  // go out there too (to its peer optimiser), also while the radio is cut; the radio then brings
  // only the peers' descriptors.
  std::optional<dds::Topic<cdc_msg_Descriptor>> t_desc_local;
  std::optional<dds::Topic<cdc_msg_LoopClosure>> t_loop_local;
  std::optional<dds::Reader<cdc_msg_Descriptor>> r_desc_local;
  std::optional<dds::Writer<cdc_msg_LoopClosure>> w_loop_local;
  if (domains.split()) {
    t_desc_local.emplace(local, topics::kDescriptor);
    t_loop_local.emplace(local, topics::kLoopClosure);
    r_desc_local.emplace(local, *t_desc_local, dds::qos::event_stream(1024));
    w_loop_local.emplace(local, *t_loop_local, dds::qos::event_stream(4096));
  }
  // Descriptors arrive live (volatile), and those missed on request: a gap in a robot's keyframe
  // ids is asked for on cdc/place/descriptor_sync and the owner's descriptor service sends just that
  // range again, in this robot's partition. The sequencer holds back what came after a gap until
  // it is filled, so that every robot's descriptors are searched in keyframe order.
  dds::Topic<cdc_msg_DescriptorSync> t_sync(participant, topics::kDescriptorSync);
  dds::Reader<cdc_msg_Descriptor> r_desc(participant, t_desc, dds::qos::event_stream(1024));
  dds::Reader<cdc_msg_Descriptor> r_desc_resent(participant, t_desc,
                                                dds::qos::event_stream(1024).partitions({dds::partitions::robot(me)}));
  dds::Writer<cdc_msg_DescriptorSync> w_sync(participant, t_sync, dds::qos::event_stream(256));
  DescriptorSequencer sequencer(o.sequencer);
  SearchQueue to_search;  // delivered in order by the sequencer, searched one per pass, robots in turn
  uint64_t to_search_peak = 0;
  std::vector<double> loop_latencies_s;  // published loops: from the later descriptor coming in

  // Peers' periodic status (their peer optimisers'): a peer that makes no keyframes (stopped, or at
  // the end of a mission) is still heard through it, so that the clouds parked for it are asked for.
  dds::Topic<cdc_msg_RobotStatus> t_status(participant, topics::kRobotStatus);
  dds::Reader<cdc_msg_RobotStatus> r_status(participant, t_status, dds::qos::keyed_state());
  dds::Reader<cdc_msg_CloudRequest> r_req(participant, t_req, dds::qos::event_stream(256));
  dds::Reader<cdc_msg_CloudReply> r_rep(participant, t_rep, dds::qos::event_stream(256).partitions(dds::partitions::own_reader(me)));
  // Loops go only where they are needed: an own-robot loop in this robot's partition (its peer
  // optimiser, the central), a loop with peer r in both robots' partitions; never to a third robot.
  dds::Writer<cdc_msg_LoopClosure> w_loop(participant, t_loop,
                                          dds::qos::event_stream(4096).partitions({dds::partitions::robot(me)}));
  dds::PerRobotWriters<cdc_msg_LoopClosure> w_loop_with(participant, t_loop, dds::qos::event_stream(4096), o.robots, me,
                                                        {dds::partitions::robot(me)});
  const auto write_loop = [&](const cdc_msg_LoopClosure& m) {
    const uint32_t other = m.robot_a == me ? m.robot_b : m.robot_a;
    dds::Writer<cdc_msg_LoopClosure>* to = w_loop_with.to(other);
    (to != nullptr ? *to : w_loop).write(m);
  };
  dds::Writer<cdc_msg_CloudRequest> w_req(participant, t_req, dds::qos::event_stream(256));
  // Cloud replies go only to the robot that asked.
  dds::PerRobotWriters<cdc_msg_CloudReply> w_rep_to(participant, t_rep, dds::qos::event_stream(256), o.robots, me);
  dds::GuardCondition stop;
  dds::ShutdownSignal::add_guard(&stop);
  dds::ReadCondition rc_kf(r_kf.handle()), rc_desc(r_desc.handle()), rc_desc_resent(r_desc_resent.handle()),
      rc_req(r_req.handle()), rc_rep(r_rep.handle());
  dds::WaitSet ws;  // conditions of both domains
  ws.attach(stop.handle(), 0);
  ws.attach(rc_kf.handle(), 1);
  ws.attach(rc_desc.handle(), 2);
  ws.attach(rc_req.handle(), 3);
  ws.attach(rc_rep.handle(), 4);
  ws.attach(rc_desc_resent.handle(), 5);
  std::optional<dds::ReadCondition> rc_desc_local;
  if (r_desc_local) {
    rc_desc_local.emplace(r_desc_local->handle());
    ws.attach(rc_desc_local->handle(), 6);
  }

  dds::ValidationLimits limits;
  limits.robot_count = o.robots;
  dds::RejectionCounter rejected;
  const auto t0 = Clock::now();
  auto now_ns = [&] { return std::chrono::duration_cast<Nanos>(Clock::now() - t0); };
  LoopCore core(o.core, me);
  // A peer is in reach while heard from within peer_timeout_ms; one heard again after a silence
  // gets the loops involving it that it may have missed meanwhile (kept here by a handle of their own).
  PeerReach reach(me, o.reach);
  std::map<uint64_t, cdc_msg_LoopClosure> written_loops;  // by handle: numbers start again with each incarnation
  uint64_t next_written = 0;
  const std::function<bool(uint32_t)> in_reach = [&](uint32_t robot) { return reach.in_reach(robot, now_ns()); };
  core.set_reachable(in_reach);
  uint64_t next_request = 1, duplicate_replies = 0, requests_served = 0, requests_unknown = 0, loops_sent = 0, points_served = 0;
  std::string last_backlog;
  // The work left, for --backlog-out (LoopNodeOptions::backlog_out), written when it changes.
  auto write_backlog = [&] {
    if (o.backlog_out.empty()) return;
    // Descriptors waiting: to be searched, or known to exist and not received yet (gaps, a peer's tail).
    const std::string line = std::to_string(to_search.size() + sequencer.missing()) + ' ' +
                             std::to_string(core.pending_requests()) + ' ' +
                             std::to_string(core.parked_requests()) + ' ' + std::to_string(loops_sent) + '\n';
    if (line == last_backlog) return;
    const std::string tmp = o.backlog_out + ".tmp";
    std::ofstream(tmp, std::ios::trunc) << line;
    std::rename(tmp.c_str(), o.backlog_out.c_str());
    last_backlog = line;
  };
  uint32_t incarnation = 0;
  // Loop numbers per incarnation, kept in the state file across restarts of this service alone.
  LoopNumbering numbering(o.state_file);
  if (!numbering.last_error().empty()) {
    spdlog::error("{}", numbering.last_error());
  } else if (const auto st = numbering.stored()) {
    spdlog::info("loop numbering state {}: incarnation {}, next loop {}", o.state_file, st->first, st->second);
  }
  uint64_t numbering_failures_logged = 0;
  PeerTraffic traffic;
  spdlog::info("loop-closure service of robot {} up: {} robots, PCM chi2 {}, domain {}{}", me, o.robots,
               o.core.pcm.chi2_threshold, o.domain,
               domains.split() ? ", own keyframes, descriptors and loops on local domain " + std::to_string(o.local_domain)
                               : std::string());

  auto handle = [&](LoopEvents ev) {
    for (const CloudWanted& c : ev.requests) {
      cdc_msg_CloudRequest q{};
      q.requester_robot_id = me;
      q.request_id = next_request++;
      q.requester_incarnation = incarnation;
      q.owner_robot_id = c.robot;
      q.keyframe_id = c.id;
      q.stamp_ns = dds::now_ns();
      w_req.write(q);
      spdlog::debug("requested cloud {}/{} (request {})", c.robot, c.id, q.request_id);
      traffic.out(dds::serialized_size(q), c.robot);
    }
    for (const Verification& v : ev.verifications) {
      spdlog::debug("verified {}/{} against {}/{}: {}, fitness {:.3f} m^2, overlap {:.2f}, guess {:.1f} m, moved {:.2f} m",
                    v.query_robot, v.query_id, v.candidate_robot, v.candidate_id,
                    v.passed ? "passed" : (v.converged ? "failed" : "not converged"), v.fitness, v.overlap, v.guess_m,
                    v.correction_m);
    }
    for (const LoopOut& l : ev.loops) {
      cdc_msg_LoopClosure m{};
      m.robot_a = l.robot_a;
      m.keyframe_a = l.keyframe_a;
      m.robot_b = l.robot_b;
      m.keyframe_b = l.keyframe_b;
      m.sender_robot_id = me;
      m.sender_incarnation = incarnation;
      const uint64_t resumed = numbering.stats().resumed;
      m.loop_seq = numbering.take(incarnation);
      if (numbering.stats().resumed != resumed) {
        spdlog::info("incarnation {} as before the restart: loop numbers go on from {}", incarnation, m.loop_seq);
      }
      if (const uint64_t f = numbering.stats().save_failures; f != numbering_failures_logged) {
        numbering_failures_logged = f;
        if (f == 1 || f % 100 == 0) {  // the first, then every hundredth: a read-only disk fails every loop
          spdlog::error("{} (failure {}; loops are still written)", numbering.last_error(), f);
        }
      }
      m.stamp_ns = dds::now_ns();
      m.status = l.withdrawn ? cdc_msg_LOOP_WITHDRAWN : cdc_msg_LOOP_ACCEPTED;
      m.T_a_b = dds::to_msg(l.T_a_b);
      dds::information_to_msg(l.information, m.information);
      m.fitness = static_cast<float>(l.fitness);
      write_loop(m);
      if (w_loop_local) w_loop_local->write(m);
      ++loops_sent;
      if (!l.withdrawn) {
        if (const auto lat = to_search.latency_s(l, now_ns())) loop_latencies_s.push_back(*lat);
      }
      const uint64_t id = next_written++;
      written_loops[id] = m;
      if (const auto gone = reach.published(id, m.robot_a, m.keyframe_a, m.robot_b, m.keyframe_b, l.withdrawn, now_ns())) {
        written_loops.erase(*gone);
      }
      spdlog::info("{} loop {}/{} - {}/{} (fitness {:.3f})", l.withdrawn ? "withdrew" : "published", l.robot_a,
                   l.keyframe_a, l.robot_b, l.keyframe_b, l.fitness);
    }
  };

  while (!dds::ShutdownSignal::requested()) {
    ws.wait(std::chrono::milliseconds(to_search.empty() ? o.tick_ms : 0));
    const Nanos now = now_ns();
    // Peers' status: who is in reach (for the parked cloud requests).
    r_status.take(64).for_each_valid([&](const cdc_msg_RobotStatus& m, const dds_sample_info_t&) {
      if (m.robot_id == me || m.is_central) return;
      if (rejected.record(topics::kRobotStatus, dds::validate(m, limits))) {
        spdlog::warn("rejected robot status: {}", rejected.last_reason());
        return;
      }
      traffic.in(dds::serialized_size(m), m.robot_id);
      reach.heard(m.robot_id, now_ns());
      // Its last keyframe: descriptors it made out of range just before it stopped making keyframes have
      // nothing after them to show the gap; the sequencer asks for them from this mark.
      if (m.last_keyframe_id >= 0 && m.last_keyframe_id <= std::numeric_limits<uint32_t>::max()) {
        sequencer.announce(m.robot_id, static_cast<uint32_t>(m.last_keyframe_id), now);
      }
    });
    // Peers' cloud requests before descriptors: serving one is cheap, and a requester gives up after its timeout
    // (descriptor bursts after a reconnection can take seconds to search and verify).
    r_req.take(64).for_each_valid([&](const cdc_msg_CloudRequest& m, const dds_sample_info_t&) {
      if (m.owner_robot_id != me) {
        return;
      }
      if (rejected.record(topics::kCloudRequest, dds::validate(m, limits))) {
        spdlog::warn("rejected cloud request: {}", rejected.last_reason());
        return;
      }
      traffic.in(dds::serialized_size(m), m.requester_robot_id);
      reach.heard(m.requester_robot_id, now_ns());
      cdc_msg_CloudReply rep{};
      rep.requester_robot_id = m.requester_robot_id;
      rep.request_id = m.request_id;
      rep.owner_robot_id = me;
      rep.owner_incarnation = incarnation;
      rep.keyframe_id = m.keyframe_id;
      const std::vector<Eigen::Vector3f>* cloud = core.cloud(me, m.keyframe_id);
      rep.found = cloud != nullptr;
      dds::compact::PackedCloud packed;
      packed.resolution_m = o.reply_resolution_m;
      if (cloud != nullptr) {
        packed = dds::compact::pack_points(*cloud, o.reply_resolution_m);
        ++requests_served;
        points_served += packed.count;
      } else {
        ++requests_unknown;
      }
      rep.point_count = packed.count;
      rep.resolution_m = packed.resolution_m;
      dds::borrow(rep.packed_points, packed.bytes);
      dds::Writer<cdc_msg_CloudReply>* to = w_rep_to.to(m.requester_robot_id);
      if (to == nullptr) return;  // validated above
      to->write(rep);
      traffic.out(dds::serialized_size(rep), m.requester_robot_id);
      spdlog::debug("served cloud {}/{} to robot {}: {} points in {} B, request {} ms old", me, m.keyframe_id,
                    m.requester_robot_id, packed.count, packed.bytes.size(), (dds::now_ns() - m.stamp_ns) / 1'000'000);
    });
    r_kf.take(64).for_each_valid([&](const cdc_msg_Keyframe& m, const dds_sample_info_t&) {
      if (m.robot_id != me) {
        return;
      }
      if (rejected.record(topics::kKeyframe, dds::validate(m, limits))) {
        spdlog::warn("rejected keyframe: {}", rejected.last_reason());
        return;
      }
      incarnation = m.incarnation;
      KeyframeIn kf;
      kf.robot = m.robot_id;
      kf.id = m.keyframe_id;
      kf.T_prev = dds::to_eigen(m.T_prev_keyframe);
      kf.information = dds::information_to_eigen(m.information);
      kf.T_odom = dds::to_eigen(m.T_odom_keyframe);
      kf.cloud.reserve(m.cloud._length);
      for (uint32_t i = 0; i < m.cloud._length; ++i) {
        kf.cloud.emplace_back(m.cloud._buffer[i].x, m.cloud._buffer[i].y, m.cloud._buffer[i].z);
      }
      handle(core.add_keyframe_data(std::move(kf), now));
    });
    auto on_descriptor = [&](const cdc_msg_Descriptor& m, const dds_sample_info_t&) {
      dds::Validation v = dds::validate(m, limits);
      if (v && (m.rings != o.core.scan_context.rings || m.sectors != o.core.scan_context.sectors ||
                std::abs(m.max_range - o.core.scan_context.max_range_m) > 1e-3)) {
        v = dds::Validation::fail("rings/sectors/max_range: descriptor of shape " + std::to_string(m.rings) + "x" +
                                  std::to_string(m.sectors) + " to " + std::to_string(m.max_range) +
                                  " m, this service uses " + std::to_string(o.core.scan_context.rings) + "x" +
                                  std::to_string(o.core.scan_context.sectors) + " to " +
                                  std::to_string(o.core.scan_context.max_range_m) + " m");
      }
      if (rejected.record(topics::kDescriptor, v)) {
        spdlog::warn("rejected descriptor: {}", rejected.last_reason());
        return;
      }
      if (m.robot_id != me) {
        traffic.in(dds::serialized_size(m), m.robot_id);
        reach.heard(m.robot_id, now_ns());
      }
      for (DescriptorIn& d : sequencer.add(DescriptorIn{m.robot_id, m.keyframe_id, dds_lidar::descriptor_from_msg(m),
                                                        dds::to_eigen(m.pose_hint)})) {
        to_search.push(std::move(d), now_ns());
      }
    };
    // Descriptors enter the sequencer as they arrive, so that a gap being filled shows at once: taken
    // one per pass, an answer waiting behind a burst of verifications after a reconnection looked
    // like no answer, and the gap was asked for again (the same range sent up to five times, then
    // skipped: KITTI-05 (b), 1,060 duplicates and 212 of robot 2's descriptors never searched).
    r_desc_resent.take(256).for_each_valid(on_descriptor);  // a resend asked for comes here, also the robot's own
    r_desc.take(256).for_each_valid([&](const cdc_msg_Descriptor& m, const dds_sample_info_t& i) {
      // With a local domain the robot's own live descriptors come there; their radio copies are
      // dropped before any work.
      if (!(r_desc_local && m.robot_id == me)) on_descriptor(m, i);
    });
    if (r_desc_local) {
      r_desc_local->take(256).for_each_valid([&](const cdc_msg_Descriptor& m, const dds_sample_info_t& i) {
        if (m.robot_id == me) on_descriptor(m, i);
      });
    }
    {
      std::vector<DescriptorIn> released;
      for (const SyncWanted& w : sequencer.wanted(now, in_reach, released)) {
        cdc_msg_DescriptorSync q{};
        q.requester_robot_id = me;
        q.owner_robot_id = w.robot;
        q.first_keyframe_id = w.first;
        q.last_keyframe_id = w.last;
        q.stamp_ns = dds::now_ns();
        w_sync.write(q);
        traffic.out(dds::serialized_size(q), w.robot);
        spdlog::debug("asked robot {} for its descriptors {}..{}", w.robot, w.first, w.last);
      }
      for (DescriptorIn& d : released) to_search.push(std::move(d), now);
    }
    // One descriptor (and below one cloud reply) searched per pass: each can start registrations, and
    // between them peers' cloud requests and this robot's own keyframes must not wait (a burst of
    // descriptors after a reconnection takes many seconds to search and verify).
    to_search_peak = std::max<uint64_t>(to_search_peak, to_search.size());
    if (auto d = to_search.pop()) handle(core.add_descriptor(std::move(*d), now));
    r_rep.take(1).for_each_valid([&](const cdc_msg_CloudReply& m, const dds_sample_info_t&) {
      if (m.requester_robot_id != me) {
        return;
      }
      if (rejected.record(topics::kCloudReply, dds::validate(m, limits))) {
        spdlog::warn("rejected cloud reply: {}", rejected.last_reason());
        return;
      }
      traffic.in(dds::serialized_size(m), m.owner_robot_id);
      // Answered is what the core still waits for (pending, or parked to be asked again: a late answer
      // to an earlier attempt is as good as the awaited one); the request id itself is informational.
      if (!core.is_wanted(m.owner_robot_id, m.keyframe_id)) {
        if (core.cloud(m.owner_robot_id, m.keyframe_id) != nullptr) {
          ++duplicate_replies;  // the answer to both attempts of a request asked again: one was used
          return;
        }
        rejected.record(topics::kCloudReply, dds::Validation::fail("keyframe_id: answers no open request of this robot"));
        spdlog::warn("rejected cloud reply: {}", rejected.last_reason());
        return;
      }
      if (!m.found) {
        core.on_cloud_missing(m.owner_robot_id, m.keyframe_id, now_ns());
        return;
      }
      std::vector<Eigen::Vector3f> cloud;
      dds::compact::unpack_points(m.packed_points._buffer, m.packed_points._length, m.point_count, m.resolution_m,
                                  cloud);  // validated above
      handle(core.on_cloud(m.owner_robot_id, m.keyframe_id, std::move(cloud), now));
    });
    handle(core.tick(now_ns()));
    write_backlog();
    if (const std::vector<uint64_t> again = reach.due(now_ns()); !again.empty()) {
      for (uint64_t id : again) write_loop(written_loops.at(id));
      spdlog::info("wrote {} loops again (loops {}..{}) for a peer heard again after a silence", again.size(),
                   written_loops.at(again.front()).loop_seq, written_loops.at(again.back()).loop_seq);
    }
  }
  dds::ShutdownSignal::remove_guard(&stop);
  if (!o.stats_out.empty()) {
    const LoopStats& s = core.stats();
    nlohmann::json peers = nlohmann::json::object();
    for (const auto& [robot, b] : traffic.peer) {
      peers[std::to_string(robot)] = {{"sent", b.first}, {"received", b.second}};
    }
    const geometry::ErrorStats latency = geometry::compute_stats(loop_latencies_s);
    nlohmann::json j{{"robot", me},
                     {"keyframes", core.keyframes()},
                     {"loops_published", loops_sent},
                     {"peer_silences", reach.stats().silences},
                     {"loops_written_again", reach.stats().loops_due},
                     {"loops_forgotten", reach.stats().forgotten},
                     {"loop_numbering", {{"state_file", o.state_file},
                                         {"resumed", numbering.stats().resumed},
                                         {"state_errors", numbering.stats().state_errors},
                                         {"save_failures", numbering.stats().save_failures}}},
                     {"queries", s.queries},
                     {"reverse_queries", s.reverse_queries},
                     {"intra_gated", s.intra_gated},
                     {"skipped_near_requested", s.skipped_near_requested},
                     {"left_to_lower_robot", s.left_to_lower_robot},
                     {"verified_with_neighbour", s.verified_with_neighbour},
                     {"reaim_too_far", s.reaim_too_far},
                     {"clouds_prepared", s.prepared},
                     {"prepared_clouds_reused", s.prepared_reused},
                     {"verified", s.verified},
                     {"verification_failed", s.verification_failed},
                     {"verification_failed_by", {{"not_converged", s.failed_not_converged},
                                                 {"fitness", s.failed_fitness},
                                                 {"overlap", s.failed_overlap}}},
                     {"intra_accepted", s.intra_accepted},
                     {"inter_accepted", s.inter_accepted},
                     {"withdrawn", s.withdrawn},
                     {"cloud_requests", s.requests},
                     {"cloud_replies", s.replies},
                     {"cloud_missing", s.missing},
                     {"cloud_timed_out", s.timed_out},
                     {"cloud_requests_retried", s.requests_retried},
                     {"cloud_requests_abandoned", s.requests_abandoned},
                     {"cloud_replies_duplicate", duplicate_replies},
                     {"cloud_unreachable", s.unreachable},
                     {"requests_served", requests_served},
                     {"descriptor_sync_requests", sequencer.stats().sync_requests},
                     {"descriptor_duplicates", sequencer.stats().duplicates},
                     {"descriptor_gaps_skipped", sequencer.stats().gaps_skipped},
                     {"descriptor_ids_skipped", sequencer.stats().ids_skipped},
                     {"descriptors_waiting_peak", to_search_peak},
                     {"loop_latency_s", {{"count", latency.count},
                                         {"median", latency.median},
                                         {"p90", latency.p90},
                                         {"max", latency.max}}},
                     {"points_served", points_served},
                     {"requests_unknown_keyframe", requests_unknown},
                     {"bytes_per_peer", peers},
                     {"radio_cuts", domains.radio_cuts()},
                     {"rejected", rejected.by_topic()},
                     {"rejected_samples", rejected.total()}};
    j["topics"] = dds::topic_traffic_json();
    std::ofstream(o.stats_out) << j.dump(2) << '\n';
  }
  spdlog::info("stopped: {} loop messages, {} rejected samples", loops_sent, rejected.total());
  return 0;
}

}  // namespace cdc::loops
