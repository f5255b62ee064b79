// The peer optimiser's messages to and from PeerCore's types: every field the node relies on.
#include "../src/peer_messages.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/validate.hpp"

#include <gtest/gtest.h>

namespace cdc::peer {
namespace {

Eigen::Isometry3d pose(double x, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, 2.0, -1.0);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

TEST(PeerMessages, ModeAndReasonBothWays) {
  for (Mode m : {Mode::kCentralized, Mode::kDistributed}) EXPECT_EQ(from_msg(to_msg(m)), m);
  EXPECT_EQ(to_msg(SwitchReason::kStartup), cdc_msg_REASON_STARTUP);
  EXPECT_EQ(to_msg(SwitchReason::kLivelinessLost), cdc_msg_REASON_LIVELINESS_LOST);
  EXPECT_EQ(to_msg(SwitchReason::kOutOfRange), cdc_msg_REASON_OUT_OF_RANGE);
  EXPECT_EQ(to_msg(SwitchReason::kBackInRange), cdc_msg_REASON_BACK_IN_RANGE);
}

TEST(PeerMessages, IncomingMessagesForTheCore) {
  cdc_msg_Keyframe k{};
  k.keyframe_id = 7;
  k.incarnation = 2;
  k.stamp_ns = 123;
  k.T_odom_keyframe = dds::to_msg(pose(1.0, 0.1));
  k.T_prev_keyframe = dds::to_msg(pose(0.5, 0.0));
  dds::information_to_msg(Matrix6d::Identity() * 4.0, k.information);
  const OwnKeyframe kf = own_keyframe(k);
  EXPECT_EQ(kf.id, 7u);
  EXPECT_EQ(kf.incarnation, 2u);
  EXPECT_EQ(kf.stamp_ns, 123);
  EXPECT_TRUE(kf.T_odom.isApprox(pose(1.0, 0.1), 1e-12));
  EXPECT_TRUE(kf.T_prev.isApprox(pose(0.5, 0.0), 1e-12));
  EXPECT_DOUBLE_EQ(kf.information(5, 5), 4.0);

  // robots and keyframes a, b; sender, its incarnation, loop seq; stamp, status, T_a_b, information, fitness
  cdc_msg_LoopClosure l{0, 4, 1, 5, 1, 3, 9, 0, cdc_msg_LOOP_WITHDRAWN, dds::to_msg(pose(2.0, 0.2)), {}, 0.0f};
  const LoopRecord r = loop_record(l);
  EXPECT_EQ(std::make_tuple(r.sender, r.sender_incarnation, r.seq, r.robot_a, r.keyframe_a, r.robot_b, r.keyframe_b),
            std::make_tuple(1u, 3u, 9u, 0u, 4u, 1u, 5u));
  EXPECT_TRUE(r.withdrawn);
  EXPECT_TRUE(r.T_a_b.isApprox(pose(2.0, 0.2), 1e-12));

  const cdc_msg_Acknowledgement a{1, 2, 4, 0, 41, -1};  // robot 1 in incarnation 2, central 4: keyframes 0..41
  const AckIn ack = ack_in(a);
  EXPECT_EQ(std::make_tuple(ack.central_incarnation, ack.robot_incarnation, ack.keyframe, ack.loop_seq),
            std::make_tuple(4u, 2u, int64_t{41}, int64_t{-1}));
}

// A keyframe for the central is the core's keyframe without a cloud, its cloud a KeyframeCloud that
// names the same keyframe and lends the node's packed bytes; the sequence names the newest.
TEST(PeerMessages, KeyframesForTheCentralAndTheSequence) {
  const OwnKeyframe k{9, 3, 456, pose(1.0, 0.1), pose(0.5, 0.0), Matrix6d::Identity() * 2.0};
  const cdc_msg_Keyframe m = keyframe_message(1, k);
  EXPECT_EQ(std::make_tuple(m.robot_id, m.keyframe_id, m.incarnation, m.stamp_ns, m.point_count, m.cloud._length),
            std::make_tuple(1u, 9u, 3u, int64_t{456}, 0u, 0u));
  EXPECT_TRUE(dds::validate(m, dds::ValidationLimits{}));
  dds::compact::PackedCloud packed = dds::compact::pack_points({{1.0f, 2.0f, 3.0f}, {-1.0f, 0.5f, 0.0f}}, 0.02f);
  const cdc_msg_KeyframeCloud c = keyframe_cloud_message(1, k, packed);
  EXPECT_EQ(std::make_tuple(c.robot_id, c.keyframe_id, c.incarnation, c.stamp_ns, c.point_count, c.resolution_m),
            std::make_tuple(1u, 9u, 3u, int64_t{456}, 2u, 0.02f));
  EXPECT_EQ(c.packed_points._buffer, packed.bytes.data());
  EXPECT_EQ(c.packed_points._length, packed.bytes.size());
  EXPECT_TRUE(dds::validate(c, dds::ValidationLimits{}));
  const OwnKeyframe back = own_keyframe(m);
  EXPECT_TRUE(back.T_odom.isApprox(k.T_odom, 1e-12));
  EXPECT_TRUE(back.T_prev.isApprox(k.T_prev, 1e-12));
  EXPECT_DOUBLE_EQ(back.information(2, 2), 2.0);

  EXPECT_EQ(keyframe_sequence(1, nullptr).newest_keyframe_id, -1);
  const cdc_msg_KeyframeSequence s = keyframe_sequence(1, &k);
  EXPECT_EQ(std::make_tuple(s.robot_id, s.incarnation, s.newest_keyframe_id, s.stamp_ns),
            std::make_tuple(1u, 3u, int64_t{9}, int64_t{456}));
  EXPECT_TRUE(dds::to_eigen(s.T_odom_keyframe).isApprox(k.T_odom, 1e-12));
}

TEST(PeerMessages, CentralResultsAndSeparatorsKeepTheirPoses) {
  std::vector<cdc_msg_KeyframePose> poses{{1, 3, dds::to_msg(pose(3.0, 0.3))}, {1, 4, dds::to_msg(pose(4.0, 0.4))}};
  cdc_msg_OptimizedPoses m{};
  m.robot_id = 1;
  m.sender_incarnation = 6;
  m.graph_version = 12;
  m.source = cdc_msg_SOURCE_CENTRAL_HINT;
  m.T_world_robot = dds::to_msg(pose(-1.0, 0.5));
  dds::borrow(m.poses, poses);
  const CentralResult c = central_result(m);
  EXPECT_EQ(c.central_incarnation, 6u);
  EXPECT_EQ(c.version, 12u);
  EXPECT_TRUE(c.from_hint);
  EXPECT_TRUE(c.T_world_robot.isApprox(pose(-1.0, 0.5), 1e-12));
  ASSERT_EQ(c.poses.size(), 2u);
  EXPECT_EQ(c.poses[1].first, 4u);
  EXPECT_TRUE(c.poses[1].second.isApprox(pose(4.0, 0.4), 1e-12));
  m.source = cdc_msg_SOURCE_CENTRAL;
  EXPECT_FALSE(central_result(m).from_hint);

  SeparatorOut out;
  out.target = 2;
  out.poses = {{5, pose(5.0, 0.1)}, {6, pose(6.0, -0.1)}};
  LoopRecord relayed{.sender = 1,
                     .sender_incarnation = 4,
                     .seq = 8,
                     .robot_a = 1,
                     .keyframe_a = 5,
                     .robot_b = 3,
                     .keyframe_b = 2,
                     .withdrawn = true,
                     .T_a_b = pose(1.0, 0.2)};
  relayed.information = Matrix6d::Identity() * 40.0;
  out.loops = {relayed};
  out.inter_robot_loops = 7;
  out.coarse_step = true;
  SeparatorStorage storage;
  const cdc_msg_SeparatorPoses s = separator_message(Origin{1, 3, 1000}, out, 17, storage);
  EXPECT_EQ(std::make_tuple(s.robot_id, s.target_robot_id, s.incarnation, s.round, s.stamp_ns),
            std::make_tuple(1u, 2u, 3u, 17u, int64_t{1000}));
  EXPECT_EQ(s.poses._buffer, storage.poses.data());
  EXPECT_EQ(s.loops._buffer, storage.loops.data());
  EXPECT_TRUE(dds::validate(s, dds::ValidationLimits{})) << dds::validate(s, dds::ValidationLimits{}).reason();
  const SeparatorOut back = separator_in(s);
  EXPECT_EQ(back.target, 2u);
  ASSERT_EQ(back.poses.size(), 2u);
  EXPECT_EQ(back.poses[0].first, 5u);
  EXPECT_TRUE(back.poses[0].second.isApprox(pose(5.0, 0.1), 1e-6)) << "separator poses travel in single precision";
  ASSERT_EQ(back.loops.size(), 1u);
  const LoopRecord& l = back.loops[0];
  EXPECT_EQ(std::make_tuple(l.sender, l.sender_incarnation, l.seq, l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b,
                            l.withdrawn),
            std::make_tuple(1u, 4u, 8u, 1u, 5u, 3u, 2u, true));
  EXPECT_TRUE(l.T_a_b.isApprox(pose(1.0, 0.2), 1e-12));
  EXPECT_TRUE(l.information.isApprox(relayed.information));
  EXPECT_EQ(back.inter_robot_loops, 7u);
  EXPECT_TRUE(back.coarse_step);
}

TEST(PeerMessages, OutgoingStateMessages) {
  const Origin o{2, 5, 123};
  const cdc_msg_ModeState unknown = mode_state(o, Mode::kDistributed, SwitchReason::kLivelinessLost, std::nullopt, 3);
  EXPECT_EQ(std::make_tuple(unknown.robot_id, unknown.incarnation, unknown.stamp_ns, unknown.transition_count),
            std::make_tuple(2u, 5u, int64_t{123}, 3u));
  EXPECT_EQ(unknown.mode, cdc_msg_MODE_DISTRIBUTED);
  EXPECT_EQ(unknown.reason, cdc_msg_REASON_LIVELINESS_LOST);
  EXPECT_DOUBLE_EQ(unknown.distance_to_central, -1.0);
  EXPECT_DOUBLE_EQ(mode_state(o, Mode::kCentralized, SwitchReason::kBackInRange, 42.5, 4).distance_to_central, 42.5);

  const cdc_msg_WorldTransform w = world_transform(o, pose(1.0, 0.2), 77);
  EXPECT_EQ(w.source, cdc_msg_SOURCE_DISTRIBUTED);
  EXPECT_EQ(w.graph_version, 77u);
  EXPECT_TRUE(dds::to_eigen(w.T_world_robot).isApprox(pose(1.0, 0.2), 1e-12));

  const cdc_msg_RobotStatus lost = robot_status(o, std::nullopt, -1, Mode::kDistributed);
  EXPECT_FALSE(lost.world_valid);
  EXPECT_TRUE(dds::to_eigen(lost.T_world_base).isApprox(Eigen::Isometry3d::Identity()));
  EXPECT_EQ(lost.last_keyframe_id, -1);
  EXPECT_FALSE(lost.is_central);
  const cdc_msg_RobotStatus placed = robot_status(o, pose(3.0, 0.0), 10, Mode::kCentralized);
  EXPECT_TRUE(placed.world_valid);
  EXPECT_EQ(placed.mode, cdc_msg_MODE_CENTRALIZED);
  EXPECT_TRUE(dds::to_eigen(placed.T_world_base).isApprox(pose(3.0, 0.0), 1e-12));
}

// A status without a world (world_valid false) carries no position, whatever its pose field holds.
TEST(PeerMessages, AStatusWithoutAWorldHasNoPosition) {
  const Origin o{0, 5, 123};
  EXPECT_FALSE(status_position(robot_status(o, std::nullopt, -1, Mode::kCentralized)));
  const auto p = status_position(robot_status(o, pose(3.0, 0.0), 10, Mode::kCentralized));
  ASSERT_TRUE(p);
  EXPECT_TRUE(p->isApprox(pose(3.0, 0.0).translation(), 1e-12));
}

TEST(PeerMessages, CorrectionCarriesItsSourceVersionAndPoses) {
  Correction c{pose(0.5, 0.05), 0.3, false, {{8, pose(8.0, 0.0)}, {9, pose(9.0, 0.1)}}};
  std::vector<cdc_msg_KeyframePose> storage;
  const cdc_msg_OptimizedPoses m = correction_message(Origin{1, 2, 50}, c, 4, storage);
  EXPECT_EQ(std::make_tuple(m.robot_id, m.sender_robot_id, m.sender_incarnation, m.graph_version, m.stamp_ns),
            std::make_tuple(1u, 1u, 2u, uint64_t{4}, int64_t{50}));
  EXPECT_EQ(m.source, cdc_msg_SOURCE_DISTRIBUTED);
  EXPECT_TRUE(dds::to_eigen(m.T_world_robot).isApprox(pose(0.5, 0.05), 1e-12));
  ASSERT_EQ(m.poses._length, 2u);
  EXPECT_EQ(m.poses._buffer[1].robot_id, 1u);
  EXPECT_EQ(m.poses._buffer[1].keyframe_id, 9u);
  EXPECT_TRUE(dds::to_eigen(m.poses._buffer[1].pose).isApprox(pose(9.0, 0.1), 1e-12));
  c.from_central = true;
  EXPECT_EQ(correction_message(Origin{1, 2, 50}, c, 5, storage).source, cdc_msg_SOURCE_CENTRAL);
}

}  // namespace
}  // namespace cdc::peer
