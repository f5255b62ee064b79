// The loop-closure node's parts that need no DDS participant: the per-peer traffic tally, the backlog
// file, the written loops kept for peers back in reach, the stats document's names and the message
// conversions.
#include "../src/backlog_file.hpp"
#include "../src/loop_messages.hpp"
#include "../src/loop_node_stats.hpp"
#include "../src/peer_traffic.hpp"
#include "../src/written_loops.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <tuple>
#include <vector>

namespace cdc::loops {
namespace {

namespace fs = std::filesystem;
using std::chrono::seconds;

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(PeerTraffic, CountsBytesEachWayPerPeerKeyedByItsId) {
  PeerTraffic t;
  t.sent(1, 100);
  t.received(1, 40);
  t.received(12, 7);
  t.sent(1, 5);
  const nlohmann::json j = t.by_peer();
  EXPECT_EQ(j, nlohmann::json::parse(R"({"1": {"sent": 105, "received": 40}, "12": {"sent": 0, "received": 7}})"));
  EXPECT_TRUE(nlohmann::json(PeerTraffic{}.by_peer()).is_object()) << "no peer: an empty object, as before any traffic";
}

TEST(BacklogFile, HoldsOneLineReplacedWhenTheBacklogChanges) {
  const fs::path dir = fs::temp_directory_path() / ("backlog_file_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path path = dir / "backlog";
  BacklogFile f(path.string());
  EXPECT_TRUE(f.update({3, 2, 1, 7}));
  EXPECT_EQ(read_file(path), "3 2 1 7\n");
  EXPECT_FALSE(f.update({3, 2, 1, 7})) << "unchanged: not written again";
  EXPECT_TRUE(f.update({0, 0, 0, 8}));
  EXPECT_EQ(read_file(path), "0 0 0 8\n");
  EXPECT_FALSE(fs::exists(path.string() + ".tmp")) << "written beside, then renamed over it";
  fs::remove_all(dir);
}

TEST(BacklogFile, AnEmptyPathKeepsNothing) {
  BacklogFile f("");
  EXPECT_FALSE(f.update({1, 1, 1, 1}));
}

cdc_msg_LoopClosure loop(uint32_t robot_a, uint32_t kf_a, uint32_t robot_b, uint32_t kf_b, uint32_t seq) {
  cdc_msg_LoopClosure m{};
  m.robot_a = robot_a;
  m.keyframe_a = kf_a;
  m.robot_b = robot_b;
  m.keyframe_b = kf_b;
  m.loop_seq = seq;
  return m;
}

TEST(WrittenLoops, APeerHeardAgainAfterASilenceGetsItsLoopsWrittenAgain) {
  PeerReachParams p;
  p.silence = seconds(3);
  p.margin = seconds(2);
  p.delay = seconds(1);
  PeerReach reach(0, p);
  WrittenLoops written(reach);
  for (int t = 0; t <= 10; ++t) reach.heard(1, seconds(t));  // peer 1's last word at 10 s
  written.wrote(loop(0, 1, 1, 1, 0), false, seconds(1));     // long before the silence: acknowledged
  written.wrote(loop(0, 2, 1, 2, 1), false, seconds(9));     // within the margin
  written.wrote(loop(0, 3, 0, 9, 2), false, seconds(12));    // the robot's own: no peer to catch up
  written.wrote(loop(1, 4, 0, 4, 3), false, seconds(12));    // written into the cut
  EXPECT_EQ(written.size(), 4u);
  reach.heard(1, seconds(30));
  EXPECT_TRUE(written.due(seconds(30)).empty()) << "waits for discovery to match the readers";
  const std::vector<const cdc_msg_LoopClosure*> again = written.due(seconds(31));
  ASSERT_EQ(again.size(), 2u);
  EXPECT_EQ(again[0]->loop_seq, 1u);
  EXPECT_EQ(again[1]->loop_seq, 3u);
  EXPECT_EQ(again[1]->keyframe_a, 4u);
}

TEST(WrittenLoops, LetsGoOfTheLoopsPeerReachForgets) {
  PeerReachParams p;
  p.keep = 2;
  PeerReach reach(0, p);
  WrittenLoops written(reach);
  for (uint32_t i = 0; i < 5; ++i) written.wrote(loop(0, i, 1, i, i), false, seconds(i));
  EXPECT_EQ(written.size(), 2u);
  EXPECT_EQ(reach.stats().forgotten, 3u);
}

TEST(LoopNodeStats, NamesTheCountersAsTheStatsFileDoes) {
  LoopStats s;
  s.requests = 5;
  s.replies = 4;
  s.prepared = 3;
  s.prepared_reused = 2;
  s.failed_fitness = 7;
  s.unreachable = 1;
  const nlohmann::json core = core_counters(s);
  EXPECT_EQ(core.at("cloud_requests"), 5);
  EXPECT_EQ(core.at("cloud_replies"), 4);
  EXPECT_EQ(core.at("clouds_prepared"), 3);
  EXPECT_EQ(core.at("prepared_clouds_reused"), 2);
  EXPECT_EQ(core.at("verification_failed_by").at("fitness"), 7);
  EXPECT_EQ(core.at("cloud_unreachable"), 1);
  EXPECT_EQ(core.size(), 22u);

  SequencerStats q;
  q.sync_requests = 6;
  q.ids_skipped = 9;
  const nlohmann::json seq = sequencer_counters(q);
  EXPECT_EQ(seq.at("descriptor_sync_requests"), 6);
  EXPECT_EQ(seq.at("descriptor_ids_skipped"), 9);

  PeerReachStats r;
  r.silences = 2;
  r.loops_due = 8;
  r.forgotten = 1;
  EXPECT_EQ(nlohmann::json(reach_counters(r)),
            nlohmann::json::parse(R"({"peer_silences": 2, "loops_written_again": 8, "loops_forgotten": 1})"));

  LoopNumberingStats n;
  n.resumed = 1;
  EXPECT_EQ(nlohmann::json(numbering_counters(n, "/var/lib/x.state")),
            nlohmann::json::parse(R"({"state_file": "/var/lib/x.state", "resumed": 1, "state_errors": 0,
                                      "save_failures": 0})"));

  const nlohmann::json latency = latency_summary({1.0, 3.0, 2.0});
  EXPECT_EQ(latency.at("count"), 3);
  EXPECT_DOUBLE_EQ(latency.at("median").get<double>(), 2.0);
  EXPECT_DOUBLE_EQ(latency.at("max").get<double>(), 3.0);
  EXPECT_EQ(nlohmann::json(latency_summary({})).at("count"), 0) << "no loop yet";
}

TEST(LoopMessages, ALoopGoesOutWithItsSenderNumberAndStatus) {
  LoopOut l{.robot_a = 0, .keyframe_a = 12, .robot_b = 2, .keyframe_b = 40, .fitness = 0.25};
  l.T_a_b.translation() = Eigen::Vector3d(1, 2, 3);
  cdc_msg_LoopClosure m = loop_message(l, 0, 3, 17);
  EXPECT_EQ(std::tie(m.keyframe_a, m.robot_b, m.keyframe_b), std::make_tuple(12u, 2u, 40u)) << "the loop's ends";
  EXPECT_EQ(std::tie(m.sender_robot_id, m.sender_incarnation, m.loop_seq), std::make_tuple(0u, 3u, 17u))
      << "its sender and number";
  EXPECT_EQ(m.status, cdc_msg_LOOP_ACCEPTED);
  EXPECT_DOUBLE_EQ(m.T_a_b.position.y, 2.0);
  EXPECT_FLOAT_EQ(m.fitness, 0.25f);
  EXPECT_GT(m.stamp_ns, 0);
  l.withdrawn = true;
  EXPECT_EQ(loop_message(l, 0, 3, 18).status, cdc_msg_LOOP_WITHDRAWN);
}

TEST(LoopMessages, ADescriptorOfAnotherShapeIsRefusedNamingBothShapes) {
  lidar::ScanContextParams sc;
  cdc_msg_Descriptor m{};
  m.rings = static_cast<decltype(m.rings)>(sc.rings);
  m.sectors = static_cast<decltype(m.sectors)>(sc.sectors);
  m.max_range = static_cast<float>(sc.max_range_m);
  EXPECT_TRUE(check_descriptor_shape(m, sc));
  m.sectors = 30;
  const dds::Validation v = check_descriptor_shape(m, sc);
  ASSERT_FALSE(v);
  EXPECT_NE(v.reason().find("descriptor of shape 20x30"), std::string::npos) << v.reason();
  EXPECT_NE(v.reason().find("this service uses 20x60"), std::string::npos) << v.reason();
}

TEST(LoopMessages, ACloudReplyCarriesThePackedCloudOrWordThatThereIsNone) {
  // Robot 1's request 9 (incarnation 0) for robot 0's keyframe 5, stamped 0.
  const cdc_msg_CloudRequest q{1, 9, 0, 0, 5, 0};
  const std::vector<Eigen::Vector3f> cloud{{1.0f, 2.0f, 3.0f}, {-1.0f, 0.5f, 0.0f}};
  dds::compact::PackedCloud packed = dds::compact::pack_points(cloud, 0.02f);
  const cdc_msg_CloudReply rep = cloud_reply(q, 0, 4, true, packed);
  EXPECT_EQ(rep.requester_robot_id, 1u);
  EXPECT_EQ(rep.request_id, 9u);
  EXPECT_EQ(rep.owner_incarnation, 4u);
  EXPECT_EQ(rep.keyframe_id, 5u);
  EXPECT_TRUE(rep.found);
  const std::vector<Eigen::Vector3f> back = reply_cloud(rep);
  ASSERT_EQ(back.size(), 2u);
  for (const Eigen::Vector3f& p : cloud) {
    EXPECT_TRUE(std::any_of(back.begin(), back.end(), [&](const Eigen::Vector3f& b) { return (b - p).norm() < 0.02f; }))
        << p.transpose() << " not in the reply";
  }

  dds::compact::PackedCloud none;
  const cdc_msg_CloudReply missing = cloud_reply(q, 0, 4, false, none);
  EXPECT_FALSE(missing.found);
  EXPECT_EQ(missing.point_count, 0u);
  EXPECT_EQ(missing.packed_points._length, 0u);
}

}  // namespace
}  // namespace cdc::loops
