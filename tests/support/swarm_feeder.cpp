// cdc-test-swarm-feeder: publishes a simulated swarm's keyframes and loop closures over DDS at a
// fixed rate, standing in for the robots' front-end and loop-closure services in back-end tests
// and soaks. The stream is generated step by step, so it can run for hours (--keyframes 0
// --minutes N). Every keyframe and loop closure is its own DDS instance: each is unregistered
// --unregister-after-s after it was written, so that neither the feeder's writers nor its readers
// keep one instance per sample ever written. With --continue-wait-ms it starts as a restarted
// front-end does: each robot's keyframes go on after the newest its back-end holds
// (cdc/backend/sequence), under that sequence's incarnation.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "swarm_stream.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <deque>
#include <thread>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

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

// Instances written, unregistered once they are older than the lag.
template <class Msg>
class InstanceLag {
 public:
  InstanceLag(cdc::dds::Writer<Msg>& writer, std::chrono::duration<double> lag) : writer_(writer), lag_(lag) {}
  void write(const Msg& m) {
    writer_.write(m);
    written_.push_back({Clock::now(), m});
  }
  void unregister_older(Clock::time_point now) {
    while (!written_.empty() && now - written_.front().first >= lag_) {
      writer_.unregister(written_.front().second);
      written_.pop_front();
    }
  }

 private:
  cdc::dds::Writer<Msg>& writer_;
  std::chrono::duration<double> lag_;
  std::deque<std::pair<Clock::time_point, Msg>> written_;
};

cdc_msg_Keyframe keyframe_msg(const cdc::test::StreamKeyframe& kf, uint32_t incarnation) {
  cdc_msg_Keyframe m{};
  m.robot_id = kf.robot;
  m.keyframe_id = kf.id;
  m.incarnation = incarnation;
  m.stamp_ns = cdc::dds::now_ns();
  m.T_odom_keyframe = cdc::dds::to_msg(kf.T_odom_keyframe);
  m.T_prev_keyframe = cdc::dds::to_msg(kf.T_prev_keyframe);
  cdc::dds::information_to_msg(kf.information, m.information);
  m.point_count = 0;
  return m;
}

cdc_msg_LoopClosure loop_msg(const cdc::test::StreamLoop& l, uint32_t incarnation) {
  cdc_msg_LoopClosure m{};
  m.robot_a = l.robot_a;
  m.keyframe_a = l.keyframe_a;
  m.robot_b = l.robot_b;
  m.keyframe_b = l.keyframe_b;
  m.sender_robot_id = l.sender;
  m.sender_incarnation = incarnation;
  m.loop_seq = l.seq;
  m.stamp_ns = cdc::dds::now_ns();
  m.status = cdc_msg_LOOP_ACCEPTED;
  m.T_a_b = cdc::dds::to_msg(l.T_a_b);
  cdc::dds::information_to_msg(l.information, m.information);
  m.fitness = 0.01f;
  return m;
}

struct FeedOptions {
  double rate_hz = 25;
  double minutes = 0;
  double unregister_after_s = 2;
  uint32_t incarnation = 4242;
  // Per robot: the first keyframe to send and its incarnation (a restarted front-end's sequence).
  std::vector<uint32_t> first, incarnations;
};

// Streams steps until the stream's keyframes or the minutes run out, or a signal; returns the
// loop closures written.
size_t feed(const cdc::test::SwarmStreamOptions& so, const FeedOptions& fo, cdc::dds::Writer<cdc_msg_Keyframe>& w_kf,
            cdc::dds::Writer<cdc_msg_LoopClosure>& w_loop) {
  cdc::test::SwarmStreamGenerator gen(so);
  InstanceLag<cdc_msg_Keyframe> kfs(w_kf, std::chrono::duration<double>(fo.unregister_after_s));
  InstanceLag<cdc_msg_LoopClosure> loops(w_loop, std::chrono::duration<double>(fo.unregister_after_s));
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(1.0 / fo.rate_hz));
  const auto start = Clock::now();
  const auto end = start + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(fo.minutes * 60));
  auto next = start;
  size_t loops_written = 0;
  const uint32_t skip = *std::min_element(fo.first.begin(), fo.first.end());
  while (!cdc::dds::ShutdownSignal::requested() &&
         (so.keyframes_per_robot == 0 || gen.steps() < so.keyframes_per_robot) &&
         (fo.minutes <= 0 || Clock::now() < end)) {
    const cdc::test::SwarmStreamGenerator::Step step = gen.next();
    const uint32_t k = gen.steps() - 1;
    if (k < skip) {
      continue;  // sent before a restart
    }
    for (const auto& kf : step.keyframes) {
      if (k >= fo.first[kf.robot]) kfs.write(keyframe_msg(kf, fo.incarnations[kf.robot]));
    }
    for (const auto& l : step.loops) loops.write(loop_msg(l, fo.incarnations[l.sender]));
    loops_written += step.loops.size();
    next += period;
    std::this_thread::sleep_until(next);
    kfs.unregister_older(Clock::now());
    loops.unregister_older(Clock::now());
  }
  return loops_written;
}

}  // namespace

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{"cdc-test-swarm-feeder: publishes a simulated swarm's keyframes and loop closures"};
  cdc::test::SwarmStreamOptions so;
  FeedOptions fo;
  uint32_t wait_readers = 0;
  int domain = -1, continue_wait_ms = 0;
  std::string graph_out;
  app.add_option("--robots", so.robots)->capture_default_str()->check(CLI::Range(1, 26));
  app.add_option("--keyframes", so.keyframes_per_robot, "keyframes per robot (0: no limit)")->capture_default_str();
  app.add_option("--minutes", fo.minutes, "stop after this long (0: no limit)")->check(CLI::Range(0.0, 1e4));
  app.add_option("--seed", so.seed)->capture_default_str();
  app.add_option("--block-w", so.block_w, "lap width [m]")->capture_default_str();
  app.add_option("--block-h", so.block_h, "lap height [m]")->capture_default_str();
  app.add_option("--excursion-robot", so.excursion_robot)->capture_default_str();
  app.add_option("--excursion-m", so.excursion_m)->capture_default_str();
  app.add_option("--rate-hz", fo.rate_hz, "keyframes per second per robot")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 1000.0));
  app.add_option("--unregister-after-s", fo.unregister_after_s, "unregister each written instance after this long")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 3600.0));
  app.add_option("--wait-readers", wait_readers, "wait for this many keyframe readers before starting");
  app.add_option("--incarnation", fo.incarnation)->capture_default_str();
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--continue-wait-ms", continue_wait_ms,
                 "start as a restarted front-end: wait this long for each robot's back-end sequence, continue it")
      ->check(CLI::Range(0, 60000));
  app.add_option("--graph-out", graph_out, "write the whole stream as g2o (needs --keyframes)");
  CLI11_PARSE(app, argc, argv);
  if (so.keyframes_per_robot == 0 && fo.minutes <= 0 && !graph_out.empty()) {
    std::fprintf(stderr, "cdc-test-swarm-feeder: --graph-out needs a bounded stream (--keyframes)\n");
    return 2;
  }

  try {
    if (!graph_out.empty()) {
      cdc::test::write_stream_g2o(cdc::test::make_swarm_stream(so), graph_out);
    }
    cdc::dds::ParticipantOptions po;
    po.domain_id = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
    cdc::dds::Participant participant(po);
    cdc::dds::Topic<cdc_msg_Keyframe> t_kf(participant, cdc::dds::topics::kKeyframe);
    cdc::dds::Topic<cdc_msg_LoopClosure> t_loop(participant, cdc::dds::topics::kLoopClosure);
    cdc::dds::Writer<cdc_msg_Keyframe> w_kf(participant, t_kf, cdc::dds::qos::event_stream(4096));
    cdc::dds::Writer<cdc_msg_LoopClosure> w_loop(participant, t_loop, cdc::dds::qos::event_stream(4096));
    fo.first.assign(so.robots, 0);
    fo.incarnations.assign(so.robots, fo.incarnation);
    if (continue_wait_ms > 0) {
      learn_sequences(participant, std::chrono::milliseconds(continue_wait_ms), fo.first, fo.incarnations);
    }
    if (wait_readers > 0 && !w_kf.wait_for_readers(wait_readers, std::chrono::seconds(30))) {
      std::fprintf(stderr, "cdc-test-swarm-feeder: only %u of %u readers matched\n", w_kf.matched_readers(),
                   wait_readers);
      return 1;
    }
    w_loop.wait_for_readers(wait_readers, std::chrono::seconds(10));
    std::printf("feeder: %u robots x %u keyframes (0: no limit), %.1f min (0: no limit), %.1f Hz\n", so.robots,
                so.keyframes_per_robot, fo.minutes, fo.rate_hz);
    std::fflush(stdout);
    const size_t loops = feed(so, fo, w_kf, w_loop);
    std::printf("feeder: done, %zu loop closures\n", loops);
    std::this_thread::sleep_for(std::chrono::milliseconds(500));  // let reliable writers flush
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cdc-test-swarm-feeder: %s\n", e.what());
    return 1;
  }
}
