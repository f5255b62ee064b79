// Radio faults of the launcher: the swarm file's syntax, its errors, and which directed pairs drop
// what at a given sim time.
#include "radio_faults.hpp"
#include "network.hpp"

#include <gtest/gtest.h>

namespace cdc::launch {
namespace {

std::vector<RadioFault> parse(const std::string& yaml, std::vector<std::string>* errors_out = nullptr) {
  std::vector<std::string> errors;
  auto faults = parse_radio_faults(YAML::Load(yaml), errors);
  if (errors_out) {
    *errors_out = errors;
  } else {
    EXPECT_TRUE(errors.empty()) << errors.front();
  }
  return faults;
}

const std::vector<uint32_t> kNodes{0, 1, 2, kCentralNode};

// Drops at sim time t_s of a fresh schedule (wall time 0: the start of every window).
std::map<DirectedPair, double> fault_drops(const std::vector<RadioFault>& faults, double t_s) {
  return FaultSchedule(faults, kNodes).drops(t_s, 0.0);
}

TEST(RadioFaults, LossOnEveryLinkDropsBothWaysForTheWholeRun) {
  const auto drops = fault_drops(parse("[{kind: loss, probability: 0.05}]"), 1234.0);
  EXPECT_EQ(drops.size(), 12u);  // every directed pair of four nodes
  for (const auto& [pair, p] : drops) EXPECT_NEAR(p, 0.05, 1e-12);
}

TEST(RadioFaults, FaultsOnOnePairCombineAsIndependentLosses) {
  const auto faults = parse(
      "[{kind: loss, probability: 0.2}, {kind: loss, probability: 0.5, between: [1, central], from_s: 10, to_s: 20}]");
  EXPECT_NEAR(fault_drops(faults, 5.0).at({1, kCentralNode}), 0.2, 1e-12);
  EXPECT_NEAR(fault_drops(faults, 15.0).at({1, kCentralNode}), 0.6, 1e-12);
  EXPECT_NEAR(fault_drops(faults, 15.0).at({kCentralNode, 1}), 0.6, 1e-12);
  EXPECT_NEAR(fault_drops(faults, 15.0).at({2, kCentralNode}), 0.2, 1e-12);
  EXPECT_NEAR(fault_drops(faults, 20.0).at({1, kCentralNode}), 0.2, 1e-12);  // to_s is exclusive
}

TEST(RadioFaults, AOneWayCutDropsOnlyItsDirection) {
  const auto faults = parse("[{kind: one_way, from: central, to: 1, from_s: 5, to_s: 12}]");
  EXPECT_TRUE(fault_drops(faults, 4.9).empty());
  const auto drops = fault_drops(faults, 5.0);
  ASSERT_EQ(drops.size(), 1u);
  EXPECT_DOUBLE_EQ(drops.at({kCentralNode, 1}), 1.0);
}

// The period runs in wall time from when the window opens (sim 10 s at wall 100 s here).
TEST(RadioFaults, AFlappingLinkIsCutInTheFirstHalfOfEachPeriodOfWallTime) {
  FaultSchedule s(parse("[{kind: flap, between: [2, central], period_s: 2, from_s: 10, to_s: 20}]"), kNodes);
  EXPECT_TRUE(s.drops(9.9, 99.0).empty());
  for (double wall : {100.0, 100.9, 102.0, 108.5, 130.0}) {
    EXPECT_EQ(s.drops(10.5, wall).size(), 2u) << wall;  // both ways
  }
  for (double wall : {101.0, 101.9, 103.5, 129.5}) EXPECT_TRUE(s.drops(10.5, wall).empty()) << wall;
  EXPECT_TRUE(s.drops(20.0, 130.0).empty());   // the window closed
  EXPECT_EQ(s.drops(15.0, 200.0).size(), 2u);  // opened again (sim time went back): a new first half
}

TEST(RadioFaults, APartitionCutsEveryLinkBetweenGroupsAndNoneWithin) {
  const auto drops = fault_drops(parse("[{kind: partition, groups: [[0, central], [1, 2]]}]"), 0.0);
  EXPECT_EQ(drops.size(), 8u);  // 2 x 2 pairs, both ways
  EXPECT_EQ(drops.count({1, 2}), 0u);
  EXPECT_EQ(drops.count({0, kCentralNode}), 0u);
  EXPECT_DOUBLE_EQ(drops.at({2, 0}), 1.0);
  EXPECT_DOUBLE_EQ(drops.at({kCentralNode, 1}), 1.0);
}

TEST(RadioFaults, EveryMistakeIsNamedWithItsIndex) {
  std::vector<std::string> errors;
  const auto faults = parse(
      "[{kind: loss, probability: 1.5}, {kind: storm}, {kind: one_way, from: 1, to: 1},"
      " {kind: flap, between: [1]}, {kind: partition, groups: [[0, 1], [1, 2]]},"
      " {kind: loss, probability: .nan}, {kind: loss, probability: 0.1, from_s: 5, to_s: 5},"
      " {kind: one_way, from: 1, to: 300}, {kind: loss, probability: 0.1, period_s: 1},"
      " {kind: loss, probability: 0.1, between: [1, x]}, {kind: loss, probability: 0.1}]",
      &errors);
  ASSERT_EQ(errors.size(), 10u);
  EXPECT_EQ(faults.size(), 1u);
  const std::vector<std::string> expected{"radio_faults[0]: probability",  "radio_faults[1]: kind",
                                          "radio_faults[2]: from and to",  "radio_faults[3]: between",
                                          "radio_faults[4]: groups: node", "radio_faults[5]: probability",
                                          "radio_faults[6]: to_s",         "radio_faults[7]: to: robot id 300",
                                          "radio_faults[8]: period_s",     "radio_faults[9]: between: 'x'"};
  for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(errors[i].rfind(expected[i], 0), 0u) << errors[i];
}

TEST(RadioFaults, NoFaultsIsAnEmptyList) {
  std::vector<std::string> errors;
  EXPECT_TRUE(parse_radio_faults(YAML::Node(), errors).empty());
  EXPECT_TRUE(parse_radio_faults(YAML::Load("{kind: loss}"), errors).empty());
  ASSERT_EQ(errors.size(), 1u);
  EXPECT_EQ(errors[0], "radio_faults: expected a list of faults");
}

}  // namespace
}  // namespace cdc::launch
