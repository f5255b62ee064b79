#include "cdc/peer_optimiser/separator_exchange.hpp"
#include "peer_test_support.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <vector>

namespace cdc::peer {
namespace {

using Sent = std::map<uint32_t, std::vector<uint32_t>>;  // peer -> own keyframe ids sent

// Robot 0: peers in range up to 50 m, a pose goes again once moved 1 cm or turned 0.01 rad, all of
// them every 10 s. Robot 1's loops touch its keyframes 5 and 6 (and 7, which it does not have yet),
// robot 2's its keyframe 8.
class SeparatorExchangeTest : public ::testing::Test {
 protected:
  SeparatorExchangeTest() {
    PeerConfig c = config(0);
    c.peer_range_m = 50;
    c.separator_min_change_m = 0.01;
    c.separator_min_change_rad = 0.01;
    c.separator_refresh = 10s;
    exchange_.emplace(c);
  }
  Sent round(Nanos now, std::optional<Eigen::Isometry3d> world_pose = std::nullopt) {
    Sent sent;
    for (const SeparatorOut& s : exchange_->round(now, wanted_, own_, world_pose)) {
      for (const auto& [id, T] : s.poses) sent[s.target].push_back(id);
    }
    return sent;
  }
  std::optional<SeparatorExchange> exchange_;
  std::map<uint32_t, std::set<uint32_t>> wanted_{{1, {5, 6, 7}}, {2, {8}}};
  std::map<uint32_t, Eigen::Isometry3d> own_{{5, pose_at(1)}, {6, pose_at(2)}, {8, pose_at(3)}};
};

TEST_F(SeparatorExchangeTest, SendsEachPeerItsPosesThenOnlyThoseThatMoved) {
  EXPECT_EQ(round(0s), (Sent{{1, {5, 6}}, {2, {8}}}));
  EXPECT_EQ(round(100ms), Sent{});
  own_[5] = pose_at(1.005);
  EXPECT_EQ(round(200ms), Sent{}) << "moved less than the dead-band";
  own_[5] = pose_at(1.02);
  own_[6] = pose_at(2, 0, 0.02);
  EXPECT_EQ(round(300ms), (Sent{{1, {5, 6}}})) << "moved, and turned";
  EXPECT_EQ(round(400ms), Sent{});
}

TEST_F(SeparatorExchangeTest, EveryRefreshSendsAllOfThem) {
  round(0s);
  EXPECT_EQ(round(9900ms), Sent{});
  EXPECT_EQ(round(10s), (Sent{{1, {5, 6}}, {2, {8}}}));
}

TEST_F(SeparatorExchangeTest, APeerOutOfRangeGetsNoneAndAllOfThemOnceBack) {
  const Eigen::Isometry3d me = pose_at(0);
  exchange_->on_peer_position(1, Eigen::Vector3d(100, 0, 0));
  EXPECT_EQ(round(0s, me), (Sent{{2, {8}}}));
  EXPECT_EQ(round(100ms), (Sent{{1, {5, 6}}})) << "without a pose of its own every peer counts as in range";
  exchange_->on_peer_position(1, Eigen::Vector3d(100, 0, 0));
  EXPECT_EQ(round(200ms, me), Sent{});
  exchange_->on_peer_position(1, Eigen::Vector3d(10, 0, 0));
  EXPECT_EQ(round(300ms, me), (Sent{{1, {5, 6}}})) << "back in range: all of them, though none moved";
}

TEST_F(SeparatorExchangeTest, ACentralizedPeerGetsNoneAndAllOfThemOnceDistributed) {
  exchange_->on_peer_mode(2, Mode::kCentralized);
  EXPECT_EQ(round(0s), (Sent{{1, {5, 6}}}));
  exchange_->on_peer_mode(2, Mode::kDistributed);
  EXPECT_EQ(round(100ms), (Sent{{2, {8}}}));
  EXPECT_EQ(round(200ms), Sent{});
}

TEST_F(SeparatorExchangeTest, APeerThatMayHaveMissedSomeGetsAllOfThemNextRound) {
  round(0s);
  exchange_->resend_to(2);
  EXPECT_EQ(round(100ms), (Sent{{2, {8}}}));
  EXPECT_EQ(round(200ms), Sent{});
}

TEST(SeparatorExchange, RelaysEachLoopOnceToEachPeerAndAgainAfterAMiss) {
  SeparatorExchange exchange(config(0));
  LoopRecord a{.sender = 0, .seq = 1, .robot_a = 0, .keyframe_a = 5, .robot_b = 1, .keyframe_b = 7};
  LoopRecord b = a;
  b.seq = 2;
  const auto relayed = [&](Nanos now, const std::vector<LoopRecord>& loops) {
    std::map<uint32_t, std::vector<uint32_t>> seqs;  // peer -> loop seqs relayed
    for (const SeparatorOut& s : exchange.round(now, {}, {}, std::nullopt, {{2, loops}})) {
      EXPECT_TRUE(s.poses.empty());
      for (const LoopRecord& l : s.loops) seqs[s.target].push_back(l.seq);
    }
    return seqs;
  };
  EXPECT_EQ(relayed(0s, {a}), (std::map<uint32_t, std::vector<uint32_t>>{{2, {1}}})) << "loops go without poses";
  EXPECT_TRUE(relayed(100ms, {a}).empty()) << "a loop relayed again";
  EXPECT_EQ(relayed(200ms, {a, b}), (std::map<uint32_t, std::vector<uint32_t>>{{2, {2}}}));
  exchange.resend_to(2);
  EXPECT_EQ(relayed(300ms, {a, b}), (std::map<uint32_t, std::vector<uint32_t>>{{2, {1, 2}}}));
  exchange.on_peer_mode(2, Mode::kCentralized);
  EXPECT_TRUE(relayed(400ms, {a, b}).empty()) << "a CENTRALIZED peer runs no coarse step";
}

}  // namespace
}  // namespace cdc::peer
