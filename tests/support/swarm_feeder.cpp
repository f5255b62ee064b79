// cdc-test-swarm-feeder: publishes a simulated swarm's keyframes and loop closures over DDS at a
// fixed rate, standing in for the robots' front-end and loop-closure services in back-end tests.
// With --continue-wait-ms it starts as a restarted front-end does: each robot's keyframes go on after
// the newest its back-end holds (cdc/backend/sequence), under that sequence's incarnation.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "swarm_stream.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <thread>
#include <vector>

namespace {

// Where each robot's keyframe sequence stands in its back-end: per robot, the first stream keyframe
// to send and its incarnation (unchanged for a robot whose back-end holds none or did not answer).
void learn_sequences(cdc::dds::Participant& participant, std::chrono::milliseconds wait, std::vector<uint32_t>& first,
                     std::vector<uint32_t>& incarnations) {
  namespace dds = cdc::dds;
  dds::Topic<cdc_msg_KeyframeSequence> topic(participant, dds::topics::kKeyframeSequence);
  dds::Reader<cdc_msg_KeyframeSequence> reader(
      participant, topic, dds::qos::keyed_state().partitions(dds::partitions::all_robots_reader()));
  std::vector<bool> heard(first.size(), false);
  const auto until = std::chrono::steady_clock::now() + wait;
  while (std::chrono::steady_clock::now() < until && std::find(heard.begin(), heard.end(), false) != heard.end()) {
    reader.take(16).for_each_valid([&](const cdc_msg_KeyframeSequence& m, const dds_sample_info_t&) {
      if (m.robot_id >= first.size()) return;
      heard[m.robot_id] = true;
      if (m.newest_keyframe_id < 0) return;
      first[m.robot_id] = static_cast<uint32_t>(m.newest_keyframe_id) + 1;
      incarnations[m.robot_id] = m.incarnation;
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  for (size_t r = 0; r < first.size(); ++r) {
    std::printf("feeder: robot %zu %s, from keyframe %u of incarnation %u\n", r,
                heard[r] ? "continues its back-end's sequence" : "heard no back-end", first[r], incarnations[r]);
  }
}

}  // namespace

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{"cdc-test-swarm-feeder: publishes a simulated swarm's keyframes and loop closures"};
  cdc::test::SwarmStreamOptions so;
  double rate_hz = 25;
  uint32_t wait_readers = 0, incarnation = 4242;
  int domain = -1, continue_wait_ms = 0;
  std::string graph_out;
  app.add_option("--robots", so.robots)->capture_default_str();
  app.add_option("--keyframes", so.keyframes_per_robot, "keyframes per robot")->capture_default_str();
  app.add_option("--seed", so.seed)->capture_default_str();
  app.add_option("--block-w", so.block_w, "lap width [m]")->capture_default_str();
  app.add_option("--block-h", so.block_h, "lap height [m]")->capture_default_str();
  app.add_option("--excursion-robot", so.excursion_robot)->capture_default_str();
  app.add_option("--excursion-m", so.excursion_m)->capture_default_str();
  app.add_option("--rate-hz", rate_hz, "keyframes per second per robot")->capture_default_str();
  app.add_option("--wait-readers", wait_readers, "wait for this many keyframe readers before starting");
  app.add_option("--incarnation", incarnation)->capture_default_str();
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--continue-wait-ms", continue_wait_ms,
                 "start as a restarted front-end: wait this long for each robot's back-end sequence, continue it")
      ->check(CLI::Range(0, 60000));
  app.add_option("--graph-out", graph_out, "write the whole stream as g2o");
  CLI11_PARSE(app, argc, argv);

  try {
    const auto stream = cdc::test::make_swarm_stream(so);
    if (!graph_out.empty()) {
      cdc::test::write_stream_g2o(stream, graph_out);
    }
    cdc::dds::ParticipantOptions po;
    po.domain_id = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
    cdc::dds::Participant participant(po);
    cdc::dds::Topic<cdc_msg_Keyframe> t_kf(participant, cdc::dds::topics::kKeyframe);
    cdc::dds::Topic<cdc_msg_LoopClosure> t_loop(participant, cdc::dds::topics::kLoopClosure);
    cdc::dds::Writer<cdc_msg_Keyframe> w_kf(participant, t_kf, cdc::dds::qos::event_stream(4096));
    cdc::dds::Writer<cdc_msg_LoopClosure> w_loop(participant, t_loop, cdc::dds::qos::event_stream(4096));
    std::vector<uint32_t> first(so.robots, 0), incarnations(so.robots, incarnation);
    if (continue_wait_ms > 0) {
      learn_sequences(participant, std::chrono::milliseconds(continue_wait_ms), first, incarnations);
    }
    const uint32_t start = *std::min_element(first.begin(), first.end());
    if (wait_readers > 0 && !w_kf.wait_for_readers(wait_readers, std::chrono::seconds(30))) {
      std::fprintf(stderr, "cdc-test-swarm-feeder: only %u of %u readers matched\n", w_kf.matched_readers(),
                   wait_readers);
      return 1;
    }
    w_loop.wait_for_readers(wait_readers, std::chrono::seconds(10));
    std::printf("feeder: %u robots x %u keyframes, %zu loop closures, %.1f Hz\n", so.robots, so.keyframes_per_robot,
                stream.loops.size(), rate_hz);
    std::fflush(stdout);
    const auto period = std::chrono::duration<double>(1.0 / rate_hz);
    auto next = std::chrono::steady_clock::now();
    size_t next_loop = 0;
    while (next_loop < stream.loops.size() && stream.loops[next_loop].step < start) ++next_loop;  // sent before
    for (uint32_t k = start; k < so.keyframes_per_robot && !cdc::dds::ShutdownSignal::requested(); ++k) {
      for (const auto& robot : stream.keyframes) {
        const auto& kf = robot[k];
        if (k < first[kf.robot]) continue;
        cdc_msg_Keyframe m{};
        m.robot_id = kf.robot;
        m.keyframe_id = kf.id;
        m.incarnation = incarnations[kf.robot];
        m.stamp_ns = cdc::dds::now_ns();
        m.T_odom_keyframe = cdc::dds::to_msg(kf.T_odom_keyframe);
        m.T_prev_keyframe = cdc::dds::to_msg(kf.T_prev_keyframe);
        cdc::dds::information_to_msg(kf.information, m.information);
        m.point_count = 0;
        w_kf.write(m);
      }
      while (next_loop < stream.loops.size() && stream.loops[next_loop].step <= k) {
        const auto& l = stream.loops[next_loop++];
        cdc_msg_LoopClosure m{};
        m.robot_a = l.robot_a;
        m.keyframe_a = l.keyframe_a;
        m.robot_b = l.robot_b;
        m.keyframe_b = l.keyframe_b;
        m.sender_robot_id = l.sender;
        m.sender_incarnation = incarnations[l.sender];
        m.loop_seq = l.seq;
        m.stamp_ns = cdc::dds::now_ns();
        m.status = cdc_msg_LOOP_ACCEPTED;
        m.T_a_b = cdc::dds::to_msg(l.T_a_b);
        cdc::dds::information_to_msg(l.information, m.information);
        m.fitness = 0.01f;
        w_loop.write(m);
      }
      next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
      std::this_thread::sleep_until(next);
    }
    std::printf("feeder: done\n");
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let reliable writers flush
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cdc-test-swarm-feeder: %s\n", e.what());
    return 1;
  }
}
