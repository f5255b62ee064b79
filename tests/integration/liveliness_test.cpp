// The mode-switch signal, end to end across processes: a writer process with a 1 s lease is
// SIGKILLed and the monitor in this process reports "lost" within lease + 200 ms; a restarted
// writer makes it report "alive" again; SIGTERM stops a writer cleanly.
#include "cdc/dds/liveliness.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "child_process.hpp"

#include <gtest/gtest.h>

#include <csignal>
#include <cstdlib>
#include <string>
#include <sys/wait.h>
#include <unistd.h>

namespace cdc::dds {
namespace {

using namespace std::chrono_literals;

constexpr auto kLease = 1000ms;
constexpr auto kSlack = 200ms;

class LivelinessAcrossProcesses : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* exe = std::getenv("CDC_LIVELINESS_WRITER");
    ASSERT_NE(exe, nullptr) << "CDC_LIVELINESS_WRITER must name the helper binary";
    writer_exe_ = exe;
    domain_ = domain_from_env(0);
    topic_ = "cdc/test/liveliness_" + std::to_string(::getpid());
  }

  test::ChildProcess start_writer() {
    return test::ChildProcess::spawn({writer_exe_, "--topic", topic_, "--lease-ms",
                                      std::to_string(kLease.count()), "--period-ms", "100", "--domain",
                                      std::to_string(domain_)});
  }

  std::string writer_exe_;
  std::string topic_;
  uint32_t domain_ = 0;
};

TEST_F(LivelinessAcrossProcesses, KillIsDetectedWithinTheLeaseAndRestartIsSeen) {
  ParticipantOptions opts;
  opts.domain_id = domain_;
  Participant participant(opts);
  Topic<cdc_msg_RobotStatus> topic(participant, topic_);
  LivelinessMonitor monitor(participant, topic.handle(), "central");
  EXPECT_EQ(monitor.state(), Liveliness::kUnknown);

  for (int round = 0; round < 2; ++round) {
    test::ChildProcess writer = start_writer();
    const auto alive = monitor.wait_for(Liveliness::kAlive, 10s);
    ASSERT_TRUE(alive) << "round " << round << ": the writer never became alive";
    EXPECT_GT(alive->alive_writers, 0);

    std::this_thread::sleep_for(300ms);  // let it assert a few times
    const auto kill_time = std::chrono::steady_clock::now();
    writer.signal(SIGKILL);
    ASSERT_TRUE(writer.wait(5s));

    const auto lost = monitor.wait_for(Liveliness::kLost, kLease + 3s);
    ASSERT_TRUE(lost) << "round " << round << ": loss not reported";
    const auto detection = std::chrono::duration_cast<std::chrono::milliseconds>(lost->when - kill_time);
    std::printf("round %d: liveliness lost reported %lld ms after SIGKILL (lease %lld ms)\n", round,
                static_cast<long long>(detection.count()), static_cast<long long>(kLease.count()));
    EXPECT_LE(detection, kLease + kSlack);
    EXPECT_GE(detection, kLease - 200ms) << "reported before the lease could have lapsed";
    EXPECT_EQ(monitor.state(), Liveliness::kLost);
  }
}

TEST_F(LivelinessAcrossProcesses, SigtermStopsTheWriterCleanly) {
  test::ChildProcess writer = start_writer();
  std::this_thread::sleep_for(300ms);
  writer.signal(SIGTERM);
  const auto status = writer.wait(3s);
  ASSERT_TRUE(status) << "writer did not exit after SIGTERM";
  ASSERT_TRUE(WIFEXITED(*status));
  EXPECT_EQ(WEXITSTATUS(*status), 0);
}

}  // namespace
}  // namespace cdc::dds
