// What a reliable writer does with samples written while the radio link is cut, across processes
// (the loopback launcher's emulated radio: SIGUSR1 makes this process's SLAM domain deaf and mute,
// SIGUSR2 brings it back). Kept, the writer sends them once the link returns; after
// Writer::discard_unacknowledged() it sends none of them, and what it writes afterwards still
// arrives. The peer optimiser relies on the second: keyframes it forwarded to the central just
// before a cut reach the central as its re-sent backlog on rejoining, not while it is DISTRIBUTED.
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/shutdown.hpp"
#include "child_process.hpp"
#include "dds_helpers.hpp"
#include "helper_process_test.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>
#include <thread>

namespace cdc::dds {
namespace {

using namespace std::chrono_literals;

// The ids a sample-reader child has printed so far.
std::set<int> ids_read(const std::string& log) {
  std::set<int> ids;
  std::ifstream in(log);
  std::string word;
  int id = 0;
  while (in >> word) {
    if (word == "sample" && in >> id) ids.insert(id);
  }
  return ids;
}

std::set<int> range(int from, int to) {
  std::set<int> s;
  for (int i = from; i < to; ++i) s.insert(i);
  return s;
}

class RadioCut : public test::HelperProcessTest {
 protected:
  RadioCut() : HelperProcessTest("CDC_SAMPLE_READER") {}
  void SetUp() override {
    HelperProcessTest::SetUp();
    dir_ = test::fresh_temp_dir("radio_cut");
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  test::ChildProcess start_reader(const std::string& topic, const std::string& log) {
    return test::ChildProcess::spawn({exe_, "--topic", topic, "--domain", std::to_string(domain_)}, log);
  }

  std::filesystem::path dir_;
};

TEST_F(RadioCut, ADiscardingWriterSendsNothingItHeldWhenTheLinkReturns) {
  const ParticipantOptions radio = test::on_domain(domain_);
  const auto local = local_domain_options(static_cast<int>(domain_ + 150), "", radio);
  ASSERT_TRUE(local.has_value());
  RobotDomains domains(radio, local, [](bool) {});
  const std::string base = "cdc/test/radio_cut_" + std::to_string(::getpid());
  Topic<cdc_msg_RobotStatus> t_kept(domains.radio(), base + "_kept"),
      t_discarding(domains.radio(), base + "_discarding");
  Writer<cdc_msg_RobotStatus> kept(domains.radio(), t_kept, qos::event_stream());
  Writer<cdc_msg_RobotStatus> discarding(domains.radio(), t_discarding, qos::event_stream());
  const std::string log_kept = (dir_ / "kept.log").string(), log_discarding = (dir_ / "discarding.log").string();
  test::ChildProcess r_kept = start_reader(t_kept.name(), log_kept);
  test::ChildProcess r_discarding = start_reader(t_discarding.name(), log_discarding);
  ASSERT_TRUE(kept.wait_for_readers(1, 10s));
  ASSERT_TRUE(discarding.wait_for_readers(1, 10s));

  cdc_msg_RobotStatus m{};
  auto write = [&](Writer<cdc_msg_RobotStatus>& w, int from, int to) {
    for (int i = from; i < to; ++i) {
      m.last_keyframe_id = i;
      w.write(m);
    }
  };
  write(kept, 0, 5);
  write(discarding, 0, 5);
  ASSERT_TRUE(
      wait_until([&] { return ids_read(log_kept).size() == 5 && ids_read(log_discarding).size() == 5; }, 10000ms));

  ::kill(::getpid(), SIGUSR1);  // the link is cut: samples 5-9 stay unacknowledged
  std::this_thread::sleep_for(300ms);
  write(kept, 5, 10);
  write(discarding, 5, 10);
  discarding.discard_unacknowledged();
  // Cyclone lets the replaced writer linger, with nothing acknowledged, for its linger duration.
  ASSERT_TRUE(discarding.wait_discarded(5s));
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(ids_read(log_kept), range(0, 5)) << "samples crossed a cut link";
  ::kill(::getpid(), SIGUSR2);

  ASSERT_TRUE(wait_until([&] { return ids_read(log_kept).size() == 10; }, 10000ms))
      << "the kept writer did not send what it held (the cut lost nothing to re-send)";
  EXPECT_EQ(ids_read(log_kept), range(0, 10));
  std::this_thread::sleep_for(2s);
  EXPECT_EQ(ids_read(log_discarding), range(0, 5)) << "the discarding writer sent samples held across the cut";

  // The fresh writer is matched again: what it writes now arrives.
  ASSERT_TRUE(wait_until([&] { return discarding.matched_readers() == 1; }, 10000ms));
  write(discarding, 10, 12);
  ASSERT_TRUE(wait_until([&] { return ids_read(log_discarding).count(11) == 1; }, 10000ms))
      << "the fresh writer's samples did not arrive";
  std::set<int> expected = range(0, 5);
  expected.insert(10);
  expected.insert(11);
  EXPECT_EQ(ids_read(log_discarding), expected);

  EXPECT_TRUE(test::terminate_all({&r_kept, &r_discarding}, 5s));
}

}  // namespace
}  // namespace cdc::dds
