// cdc-test-swarm-feeder: publishes a simulated swarm's keyframes and loop closures over DDS at a
// fixed rate, standing in for the robots' front-end and loop-closure services in back-end tests
// and soaks. The stream is generated step by step, so it can run for hours (--keyframes 0
// --minutes N). Every keyframe and loop closure is its own DDS instance: each is unregistered
// --unregister-after-s after it was written, so that neither the feeder's writers nor its readers
// keep one instance per sample ever written.
#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "swarm_stream.hpp"

#include <CLI/CLI.hpp>

#include <cstdio>
#include <deque>
#include <thread>

namespace {

using Clock = std::chrono::steady_clock;

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
  while (!cdc::dds::ShutdownSignal::requested() &&
         (so.keyframes_per_robot == 0 || gen.steps() < so.keyframes_per_robot) &&
         (fo.minutes <= 0 || Clock::now() < end)) {
    const cdc::test::SwarmStreamGenerator::Step step = gen.next();
    for (const auto& kf : step.keyframes) kfs.write(keyframe_msg(kf, fo.incarnation));
    for (const auto& l : step.loops) loops.write(loop_msg(l, fo.incarnation));
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
  int domain = -1;
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
