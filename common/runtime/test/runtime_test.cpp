#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"
#include "cdc/runtime/stats.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/qos.hpp"

#include <gtest/gtest.h>
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <vector>

namespace cdc::runtime {
namespace {

constexpr const char* kTopic = "cdc/test/runtime_progress";

dds::ParticipantOptions test_domain() {
  dds::ParticipantOptions p;
  p.domain_id = dds::domain_from_env(0);
  return p;
}

dds::ValidationLimits three_robots() {
  dds::ValidationLimits l;
  l.robot_count = 3;
  return l;
}

// Polls until n samples reached the handler or two seconds pass.
size_t poll_until(Service& service, Input<cdc_msg_ConsumerProgress>& input, size_t n) {
  size_t handled = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  while (handled < n && std::chrono::steady_clock::now() < deadline) {
    service.wait(std::chrono::milliseconds(50));
    handled += input.poll();
  }
  return handled;
}

TEST(Input, FiltersValidatesChecksCountsAndHands) {
  Service service(Domains::kSingle, test_domain(), std::nullopt, three_robots());
  std::vector<uint64_t> seen;
  Input<cdc_msg_ConsumerProgress> input(service, service.radio(), kTopic, dds::qos::event_stream(64));
  input.filter([](const cdc_msg_ConsumerProgress& m) { return m.incarnation == 1; })
      .check([](const cdc_msg_ConsumerProgress& m) {
        return m.last_scan_seq == 7 ? dds::Validation::fail("last_scan_seq: 7 is unlucky") : dds::Validation::ok();
      })
      .on([&](const cdc_msg_ConsumerProgress& m) { seen.push_back(m.last_scan_seq); });

  dds::Topic<cdc_msg_ConsumerProgress> topic(service.radio(), kTopic);
  dds::Writer<cdc_msg_ConsumerProgress> writer(service.radio(), topic, dds::qos::event_stream(64));
  ASSERT_TRUE(writer.wait_for_readers(1, std::chrono::seconds(5)));
  writer.write({0, 2, 1});  // another incarnation: not for this node
  writer.write({5, 1, 2});  // robot 5 of 3: invalid
  writer.write({1, 1, 7});  // refused by the node's own check
  writer.write({2, 1, 3});
  writer.write({0, 1, 4});

  EXPECT_EQ(poll_until(service, input, 2), 2u);
  std::sort(seen.begin(), seen.end());  // samples of different robots (instances) come in any order
  EXPECT_EQ(seen, (std::vector<uint64_t>{3, 4}));
  EXPECT_EQ(service.boundary().rejected().total(), 2u);
  EXPECT_EQ(service.boundary().rejected().count(kTopic), 2u);
  EXPECT_NE(service.boundary().rejected().last_reason().find("unlucky"), std::string::npos);
}

TEST(Input, ConvertsBeforeHandingOn) {
  Service service(Domains::kSingle, test_domain(), std::nullopt, three_robots());
  std::vector<double> seen;
  Input<cdc_msg_ConsumerProgress> input(service, service.radio(), kTopic, dds::qos::event_stream(64));
  input.on([](const cdc_msg_ConsumerProgress& m) { return static_cast<double>(m.last_scan_seq) / 2.0; },
           [&](double half) { seen.push_back(half); });
  dds::Topic<cdc_msg_ConsumerProgress> topic(service.radio(), kTopic);
  dds::Writer<cdc_msg_ConsumerProgress> writer(service.radio(), topic, dds::qos::event_stream(64));
  ASSERT_TRUE(writer.wait_for_readers(1, std::chrono::seconds(5)));
  writer.write({1, 0, 5});
  EXPECT_EQ(poll_until(service, input, 1), 1u);
  EXPECT_EQ(seen, std::vector<double>{2.5});
}

TEST(Service, WakesOnAWatchedGuard) {
  Service service(Domains::kSingle, test_domain(), std::nullopt, three_robots());
  dds::GuardCondition guard;
  service.watch(guard);
  guard.trigger();
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(service.wait(std::chrono::seconds(10)));
  EXPECT_LT(std::chrono::steady_clock::now() - t0, std::chrono::seconds(5)) << "the guard did not wake the wait";
}

struct OwnCounters {
  uint64_t scans = 0;
  double level_deg = 0;
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(OwnCounters, scans, level_deg)

TEST(Stats, OwnCountersRejectionsAndTraffic) {
  Boundary boundary(three_robots());
  EXPECT_FALSE(boundary.refuse("a", dds::Validation::ok()));
  EXPECT_TRUE(boundary.refuse("a", dds::Validation::fail("bad")));
  const nlohmann::json j = service_stats(nlohmann::json(OwnCounters{12, 0.5}), boundary);
  EXPECT_EQ(j.at("scans"), 12);
  EXPECT_DOUBLE_EQ(j.at("level_deg").get<double>(), 0.5);
  EXPECT_EQ(j.at("rejected").at("a"), 1);
  EXPECT_EQ(j.at("rejected_samples"), 1);
  EXPECT_TRUE(j.contains("topics"));

  const auto path = std::filesystem::temp_directory_path() / "cdc_runtime_test_stats.json";
  write_stats(path.string(), OwnCounters{3, 0}, boundary);
  nlohmann::json back;
  std::ifstream(path) >> back;
  EXPECT_EQ(back.at("scans"), 3);
  std::filesystem::remove(path);
  EXPECT_THROW(write_stats("/nonexistent-dir/stats.json", OwnCounters{}, boundary), std::runtime_error);
}

TEST(Boundary, EveryRefusalIsCountedAndAFloodIsLoggedOncePerPeriod) {
  Boundary boundary(three_robots());
  int lines = 0;
  for (int i = 0; i < 1000; ++i) {
    bool logged = false;
    EXPECT_TRUE(boundary.refuse("flood", dds::Validation::fail("bad"), &logged));
    lines += logged ? 1 : 0;
  }
  bool other = false;
  EXPECT_TRUE(boundary.refuse("other", dds::Validation::fail("bad"), &other));
  EXPECT_TRUE(other) << "each topic has its own log period";
  EXPECT_EQ(lines, 1) << "1,000 refusals within one log period make one log line";
  EXPECT_EQ(boundary.rejected().count("flood"), 1000u);
  EXPECT_EQ(boundary.rejected().total(), 1001u);
}

// Within one log period a refusal for another reason is logged at once; the same reason with other
// numbers (ids, counts) is not.
TEST(Boundary, EachKindOfReasonHasItsOwnLogPeriod) {
  Boundary boundary(dds::ValidationLimits{});
  bool logged = false;
  EXPECT_TRUE(boundary.refuse("scan", dds::Validation::fail("point 500: non-finite value"), &logged));
  EXPECT_TRUE(logged);
  EXPECT_TRUE(boundary.refuse("scan", dds::Validation::fail("point 7: non-finite value"), &logged));
  EXPECT_FALSE(logged) << "the same kind of reason within the period";
  EXPECT_TRUE(boundary.refuse("scan", dds::Validation::fail("empty sweep"), &logged));
  EXPECT_TRUE(logged) << "another kind of reason is named at once";
  EXPECT_EQ(boundary.rejected().count("scan"), 3u);
}

TEST(Options, SharedOptionsParseAndRobotIsChecked) {
  ServiceSpec spec{"cdc-test", "a test service", "see nowhere", kRobotService};
  ServiceOptions o;
  CLI::App app;
  add_shared_options(app, spec, o);
  std::vector<std::string> args{"--robot", "2", "--domain", "7", "--local-domain", "7", "--stats-out", "s.json"};
  std::reverse(args.begin(), args.end());
  app.parse(args);
  EXPECT_EQ(o.robot, 2u);
  EXPECT_EQ(o.domain_id(), 7u);
  EXPECT_EQ(o.stats_out, "s.json");
  EXPECT_FALSE(o.local().has_value()) << "a local domain equal to the SLAM domain is none";
  EXPECT_NO_THROW(o.check_robot(3));
  EXPECT_THROW(o.check_robot(2), UsageError);

  ServiceSpec central{"cdc-central", "no robot", "x", kStatsOption};
  ServiceOptions c;
  CLI::App app2;
  add_shared_options(app2, central, c);
  std::vector<std::string> robot_arg{"3", "--robot"};
  EXPECT_THROW(app2.parse(robot_arg), CLI::ParseError) << "--robot is not an option of a central service";
}

TEST(Options, ServiceMainMapsErrorsToExitCodes) {
  ServiceSpec spec{"cdc-test", "a test service", "x", kStatsOption};
  char name[] = "cdc-test";
  char* argv[] = {name, nullptr};
  ServiceOptions o;
  EXPECT_EQ(service_main(1, argv, spec, o, {}, [] { return 0; }), 0);
  EXPECT_EQ(service_main(1, argv, spec, o, {}, []() -> int { throw config::ConfigError("bad key"); }), 2);
  EXPECT_EQ(service_main(1, argv, spec, o, {}, []() -> int { throw UsageError("bad robot"); }), 2);
  EXPECT_EQ(service_main(1, argv, spec, o, {}, []() -> int { throw std::runtime_error("broken"); }), 1);
}

TEST(Service, KeepsTheSharedOptionsItWasBuiltFrom) {
  ServiceOptions o;
  o.robot = 1;
  o.stats_out = "stats.json";
  Service service(Domains::kSingle, o, swarm_limits(3, {200}));
  EXPECT_EQ(service.options().robot, 1u);
  EXPECT_EQ(service.options().stats_out, "stats.json");
  EXPECT_EQ(service.radio().domain_id(), o.domain_id());
  EXPECT_FALSE(service.split());
  EXPECT_EQ(service.boundary().limits().robot_count, 3u);
  EXPECT_EQ(service.boundary().limits().extra_node_ids, std::vector<uint32_t>{200});
  EXPECT_EQ(service.boundary().limits().max_scan_points, dds::ValidationLimits{}.max_scan_points);
}

// node_main's part of a service: what it built the node from.
struct NodeMainOptions {
  uint32_t robots = 2;
  std::string log_level = "warn";
  std::string label;
};
NodeMainOptions load_node_main_options(const std::string& path) {
  if (!path.empty()) throw config::ConfigError("no configuration files here");
  return NodeMainOptions{};
}
struct NodeMainFlags {
  std::string label;
  void declare(CLI::App& app) { app.add_option("--label", label); }
  void apply(NodeMainOptions& o, const ServiceOptions& common) const {
    o.label = label + "@" + std::to_string(common.robot);
  }
};
struct BuiltNode {
  static inline std::vector<std::string> built;
  BuiltNode(const ServiceOptions& common, const NodeMainOptions& o) {
    built.push_back(o.label + " stats " + common.stats_out);
  }
  void spin() {}
  void finish() {}
};

TEST(Options, NodeMainChecksTheRobotAppliesFlagsAndRunsTheNode) {
  const ServiceSpec spec{"cdc-node-main-test", "a test service", "x", kRobotOption | kStatsOption};
  const auto robots = [](const NodeMainOptions& o) { return o.robots; };
  std::vector<std::string> good{"cdc-node-main-test", "--robot", "1", "--label", "lidar", "--stats-out", "s.json"};
  std::vector<char*> argv;
  for (std::string& a : good) argv.push_back(a.data());
  EXPECT_EQ(node_main<BuiltNode>(static_cast<int>(argv.size()), argv.data(), spec, load_node_main_options, robots,
                                 NodeMainFlags{}),
            0);
  EXPECT_EQ(BuiltNode::built, std::vector<std::string>{"lidar@1 stats s.json"});

  std::vector<std::string> bad{"cdc-node-main-test", "--robot", "2"};  // the configuration names robots 0 and 1
  argv.clear();
  for (std::string& a : bad) argv.push_back(a.data());
  EXPECT_EQ(node_main<BuiltNode>(static_cast<int>(argv.size()), argv.data(), spec, load_node_main_options, robots), 2);
  EXPECT_EQ(BuiltNode::built.size(), 1u) << "no node for a robot the configuration does not have";
}

}  // namespace
}  // namespace cdc::runtime
