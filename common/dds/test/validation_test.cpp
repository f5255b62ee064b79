// Boundary validation: malformed samples are rejected with a reason that names the problem.
#include "cdc/dds/compact.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/dds/validate.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

namespace cdc::dds {
namespace {

using ::testing::HasSubstr;

// A Validation that rejects the message with a reason containing `text`.
MATCHER_P(RejectsWith, text, "") {
  *result_listener << (arg ? std::string("accepts") : "rejects: " + arg.reason());
  return !arg && arg.reason().find(text) != std::string::npos;
}

cdc_msg_Pose identity_pose() { return to_msg(Eigen::Isometry3d::Identity()); }

void identity_information(cdc_msg_Information6& info) {
  for (int i = 0; i < 36; ++i) {
    info[i] = (i % 7 == 0) ? 100.0 : 0.0;
  }
}

struct KeyframeFixture {
  KeyframeFixture() : points(3, cdc_msg_PointXYZI{1.0f, 2.0f, 3.0f, 0.5f}) {
    msg.robot_id = 1;
    msg.keyframe_id = 7;
    msg.incarnation = 42;
    msg.T_odom_keyframe = identity_pose();
    msg.T_prev_keyframe = identity_pose();
    identity_information(msg.information);
    borrow(msg.cloud, points);
    msg.point_count = 3;
  }
  cdc_msg_Keyframe msg{};
  std::vector<cdc_msg_PointXYZI> points;
};

TEST(Validation, AcceptsAWellFormedKeyframe) {
  KeyframeFixture f;
  const Validation v = validate(f.msg, ValidationLimits{});
  EXPECT_TRUE(v) << v.reason();
}

TEST(Validation, RejectsNaNPosition) {
  KeyframeFixture f;
  f.msg.T_odom_keyframe.position.y = std::numeric_limits<double>::quiet_NaN();
  const Validation v = validate(f.msg, ValidationLimits{});
  EXPECT_THAT(v, RejectsWith("T_odom_keyframe.position"));
  EXPECT_THAT(v, RejectsWith("non-finite"));
}

TEST(Validation, RejectsNaNPoint) {
  KeyframeFixture f;
  f.points[2].z = std::numeric_limits<float>::infinity();
  EXPECT_THAT(validate(f.msg, ValidationLimits{}), RejectsWith("cloud[2]"));
}

TEST(Validation, RejectsNonUnitQuaternion) {
  KeyframeFixture f;
  f.msg.T_prev_keyframe.orientation = cdc_msg_Quat{0.0, 0.0, 0.5, 1.0};
  EXPECT_THAT(validate(f.msg, ValidationLimits{}), RejectsWith("T_prev_keyframe.orientation: not a unit quaternion"));
}

TEST(Validation, QuaternionWithinToleranceIsAccepted) {
  KeyframeFixture f;
  f.msg.T_prev_keyframe.orientation = cdc_msg_Quat{0.0, 0.0, 0.0, 1.0005};
  EXPECT_TRUE(validate(f.msg, ValidationLimits{}));
}

TEST(Validation, RejectsLengthMismatch) {
  KeyframeFixture f;
  f.msg.point_count = 4;  // declared 4, three sent
  EXPECT_THAT(validate(f.msg, ValidationLimits{}), RejectsWith("declared 4 elements but 3 received (length mismatch)"));
}

TEST(Validation, RejectsOversizedCloud) {
  KeyframeFixture f;
  ValidationLimits limits;
  limits.max_cloud_points = 2;
  EXPECT_THAT(validate(f.msg, limits), RejectsWith("exceed the limit of 2"));
}

TEST(Validation, RejectsUnknownRobotId) {
  KeyframeFixture f;
  ValidationLimits limits;
  limits.robot_count = 3;
  f.msg.robot_id = 3;
  EXPECT_THAT(validate(f.msg, limits), RejectsWith("unknown robot id 3"));
}

TEST(Validation, RejectsNaNInformation) {
  KeyframeFixture f;
  f.msg.information[8] = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THAT(validate(f.msg, ValidationLimits{}), RejectsWith("information[1][2]"));
}

TEST(Validation, RejectsAsymmetricOrNonPositiveInformation) {
  KeyframeFixture f;
  f.msg.information[1] = 5.0;
  EXPECT_THAT(validate(f.msg, ValidationLimits{}).reason(), HasSubstr("not symmetric"));
  KeyframeFixture g;
  g.msg.information[35] = 0.0;
  EXPECT_THAT(validate(g.msg, ValidationLimits{}).reason(), HasSubstr("diagonal entry 5"));
}

TEST(Validation, LidarScanTimeOffsetsAndCounts) {
  std::vector<cdc_msg_LidarPoint> pts(2, cdc_msg_LidarPoint{1, 1, 1, 0.2f, 0.05f, 3});
  cdc_msg_LidarScan scan{};
  scan.robot_id = 0;
  scan.duration_ns = 100'000'000;
  borrow(scan.points, pts);
  scan.point_count = 2;
  EXPECT_TRUE(validate(scan, ValidationLimits{}));
  pts[1].time_offset = 0.2f;  // after the sweep ended
  EXPECT_THAT(validate(scan, ValidationLimits{}).reason(), HasSubstr("points[1].time_offset"));
  pts[1].time_offset = 0.01f;
  pts[0].x = std::nanf("");
  EXPECT_THAT(validate(scan, ValidationLimits{}).reason(), HasSubstr("points[0]: non-finite"));
}

TEST(Validation, ImuStampsMustIncrease) {
  std::vector<cdc_msg_ImuSample> s(3);
  for (size_t i = 0; i < s.size(); ++i) {
    s[i].stamp_ns = static_cast<int64_t>(i) * 5'000'000;
    s[i].linear_acceleration = cdc_msg_Vec3{0, 0, 9.81};
  }
  cdc_msg_ImuBatch b{};
  borrow(b.samples, s);
  b.sample_count = 3;
  EXPECT_TRUE(validate(b, ValidationLimits{}));
  s[2].stamp_ns = s[1].stamp_ns;
  EXPECT_THAT(validate(b, ValidationLimits{}).reason(), HasSubstr("samples[2].stamp_ns"));
}

TEST(Validation, DescriptorShape) {
  std::vector<uint8_t> cells(20 * 60, 3);
  cdc_msg_Descriptor d{};
  d.robot_id = 2;
  d.rings = 20;
  d.sectors = 60;
  d.max_range = 80.0f;
  d.quant_scale = 0.1f;
  d.pose_hint = to_msg_f(Eigen::Isometry3d::Identity());
  std::vector<uint8_t> packed = compact::deflate_bytes(cells.data(), cells.size());
  borrow(d.packed_cells, packed);
  EXPECT_TRUE(validate(d, ValidationLimits{}));
  d.pose_hint.orientation.w = 2.0f;
  EXPECT_THAT(validate(d, ValidationLimits{}).reason(), HasSubstr("pose_hint.orientation: not a unit quaternion"));
  d.pose_hint.orientation.w = 1.0f;
  d.sectors = 61;
  EXPECT_THAT(validate(d, ValidationLimits{}).reason(),
              HasSubstr("packed_cells: unpacks to 1200 bytes, 1220 expected"));
  d.sectors = 59;
  EXPECT_THAT(validate(d, ValidationLimits{}).reason(), HasSubstr("packed_cells: unpacks to more than the 1180 bytes"));
  d.sectors = 60;
  packed[packed.size() / 2] ^= 0x5a;  // corrupt the stream (its checksum no longer matches)
  EXPECT_THAT(validate(d, ValidationLimits{}).reason(), HasSubstr("packed_cells: corrupt packed data"));
}

TEST(Validation, DescriptorSyncRange) {
  cdc_msg_DescriptorSync q{
      .requester_robot_id = 1, .owner_robot_id = 2, .first_keyframe_id = 4, .last_keyframe_id = 4, .stamp_ns = 0};
  EXPECT_TRUE(validate(q, ValidationLimits{}));
  q.last_keyframe_id = 3;
  EXPECT_THAT(validate(q, ValidationLimits{}).reason(), HasSubstr("last_keyframe_id: 3 is before first_keyframe_id 4"));
  q.last_keyframe_id = 9;
  q.owner_robot_id = 40;
  EXPECT_THAT(validate(q, ValidationLimits{}).reason(), HasSubstr("owner_robot_id"));
}

TEST(Validation, CloudReplyPackedPoints) {
  std::vector<Eigen::Vector3f> pts = {{1, 2, 3}, {-4.5f, 0.25f, 7}, {30, -20, 1}};
  compact::PackedCloud pc = compact::pack_points(pts, 0.01f);
  cdc_msg_CloudReply r{};
  r.requester_robot_id = 1;
  r.owner_robot_id = 0;
  r.found = true;
  r.point_count = pc.count;
  r.resolution_m = pc.resolution_m;
  borrow(r.packed_points, pc.bytes);
  EXPECT_TRUE(validate(r, ValidationLimits{}));
  r.point_count = 5;
  EXPECT_THAT(validate(r, ValidationLimits{}).reason(), HasSubstr("packed_points: unpacks to 18 bytes, 30 expected"));
  r.point_count = 3;
  r.resolution_m = std::nanf("");
  EXPECT_THAT(validate(r, ValidationLimits{}).reason(), HasSubstr("resolution_m"));
  r.resolution_m = 0.01f;
  r.found = false;
  EXPECT_THAT(validate(r, ValidationLimits{}).reason(), HasSubstr("not found"));
  r.found = true;
  ValidationLimits small;
  small.max_cloud_points = 2;
  EXPECT_THAT(validate(r, small).reason(), HasSubstr("point_count: 3 points exceed the limit of 2"));
}

TEST(Validation, KeyframeCloudPackedPoints) {
  std::vector<Eigen::Vector3f> pts = {{1, 2, 3}, {-4.5f, 0.25f, 7}, {30, -20, 1}, {0, 0, 0}};
  compact::PackedCloud pc = compact::pack_points(pts, 0.02f);
  cdc_msg_KeyframeCloud c{};
  c.robot_id = 2;
  c.keyframe_id = 7;
  c.point_count = pc.count;
  c.resolution_m = pc.resolution_m;
  borrow(c.packed_points, pc.bytes);
  EXPECT_TRUE(validate(c, ValidationLimits{}));
  c.point_count = 6;
  EXPECT_THAT(validate(c, ValidationLimits{}).reason(), HasSubstr("packed_points: unpacks to 24 bytes, 36 expected"));
  c.point_count = 4;
  c.resolution_m = -0.02f;
  EXPECT_THAT(validate(c, ValidationLimits{}).reason(), HasSubstr("resolution_m"));
  c.resolution_m = 0.02f;
  c.robot_id = 40;
  EXPECT_THAT(validate(c, ValidationLimits{}).reason(), HasSubstr("robot_id"));
  c.robot_id = 2;
  ValidationLimits small;
  small.max_cloud_points = 3;
  EXPECT_THAT(validate(c, small).reason(), HasSubstr("point_count: 4 points exceed the limit of 3"));
  // Bytes beyond what the codec can make of 4 points are refused before decoding.
  std::vector<uint8_t> big(compact::packed_bound(24) + 1, 0x55);
  borrow(c.packed_points, big);
  EXPECT_THAT(validate(c, ValidationLimits{}).reason(), HasSubstr("packed_points"));
  // Corrupt bytes are named, never a crash.
  std::vector<uint8_t> corrupt = pc.bytes;
  for (size_t i = 2; i < corrupt.size(); i += 3) corrupt[i] ^= 0xA5;
  borrow(c.packed_points, corrupt);
  EXPECT_THAT(validate(c, ValidationLimits{}).reason(), HasSubstr("packed_points: "));
  // A keyframe with no points in range packs to no bytes and is valid.
  c.point_count = 0;
  c.packed_points = {};
  EXPECT_TRUE(validate(c, ValidationLimits{}));
}

TEST(Validation, LoopClosureChecks) {
  cdc_msg_LoopClosure l{};
  l.robot_a = 0;
  l.keyframe_a = 3;
  l.robot_b = 1;
  l.keyframe_b = 9;
  l.T_a_b = identity_pose();
  identity_information(l.information);
  EXPECT_TRUE(validate(l, ValidationLimits{}));
  l.robot_b = 0;
  l.keyframe_b = 3;
  EXPECT_THAT(validate(l, ValidationLimits{}).reason(), HasSubstr("to itself"));
  l.keyframe_b = 4;
  const int bad_status = 7;  // what a corrupt or newer sender could put on the wire
  std::memcpy(&l.status, &bad_status, sizeof bad_status);
  EXPECT_THAT(validate(l, ValidationLimits{}).reason(), HasSubstr("status: unknown enumerator 7"));
}

TEST(Validation, OptimizedPosesMustBelongToTheirRobot) {
  std::vector<cdc_msg_KeyframePose> poses{{2, 0, identity_pose()}, {1, 1, identity_pose()}};
  cdc_msg_OptimizedPoses m{};
  m.robot_id = 2;
  m.T_world_robot = identity_pose();
  borrow(m.poses, poses);
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("poses[1].robot_id: 1 in a message about robot 2"));
  poses[1].robot_id = 2;
  EXPECT_TRUE(validate(m, ValidationLimits{}));
}

TEST(Validation, SeparatorPosesInSinglePrecision) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(812.3456, -97.25, 4.5);
  std::vector<cdc_msg_KeyframePoseF> poses{{4, to_msg_f(T)}, {9, to_msg_f(T)}};
  cdc_msg_SeparatorPoses m{};
  m.robot_id = 1;
  m.target_robot_id = 2;
  borrow(m.poses, poses);
  EXPECT_TRUE(validate(m, ValidationLimits{}));
  poses[1].pose.orientation.w = 0.5f;
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("poses[1].pose.orientation: not a unit quaternion"));
  poses[1].pose.orientation.w = 1.0f;
  poses[0].pose.position.y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("poses[0].pose.position: non-finite component"));
  m.target_robot_id = 77;
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("target_robot_id"));
}

TEST(Validation, SeparatorPosesRelayOnlyTheSendersInterRobotLoops) {
  cdc_msg_SeparatorPoses m{};
  m.robot_id = 1;
  m.target_robot_id = 2;
  std::vector<cdc_msg_LoopClosure> loops(1);
  cdc_msg_LoopClosure& l = loops[0];
  l.robot_a = 1;
  l.keyframe_a = 4;
  l.robot_b = 3;
  l.keyframe_b = 9;
  l.sender_robot_id = 1;
  l.T_a_b = identity_pose();
  identity_information(l.information);
  borrow(m.loops, loops);
  m.inter_robot_loops = 1;
  EXPECT_TRUE(validate(m, ValidationLimits{})) << validate(m, ValidationLimits{}).reason();
  l.robot_a = 0;
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(),
              HasSubstr("loops[0]: not an inter-robot loop of the sender, robot 1 (robots 0 and 3)"));
  l.robot_a = 3;
  l.robot_b = 3;
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("loops[0]: not an inter-robot loop"));
  l.robot_a = 1;
  l.fitness = -1.0f;
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("loops[0].fitness"));
  l.fitness = 0.0f;
  l.robot_b = 99;
  EXPECT_THAT(validate(m, ValidationLimits{}).reason(), HasSubstr("loops[0].robot_b"));
}

TEST(Validation, ExtraNodeIdsAreAccepted) {
  cdc_msg_RobotStatus s{};
  s.robot_id = 200;  // a ground-station central
  ValidationLimits limits;
  EXPECT_FALSE(validate(s, limits));
  limits.extra_node_ids = {200};
  EXPECT_TRUE(validate(s, limits));
}

TEST(RejectionCounter, CountsPerTopicAndKeepsTheLastReason) {
  RejectionCounter c;
  EXPECT_FALSE(c.record("cdc/a", Validation::ok()));
  EXPECT_TRUE(c.record("cdc/a", Validation::fail("bad x")));
  EXPECT_TRUE(c.record("cdc/b", Validation::fail("bad y")));
  EXPECT_TRUE(c.record("cdc/a", Validation::fail("bad z")));
  EXPECT_EQ(c.total(), 3u);
  EXPECT_EQ(c.count("cdc/a"), 2u);
  EXPECT_EQ(c.count("cdc/none"), 0u);
  EXPECT_EQ(c.last_reason(), "cdc/a: bad z");
  EXPECT_EQ(c.by_topic().size(), 2u);
}

TEST(Convert, PoseAndInformationRoundTrip) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(1, -2, 3);
  const cdc_msg_Pose p = to_msg(T);
  // Message order is x, y, z, w.
  const Eigen::Quaterniond q(T.rotation());
  EXPECT_DOUBLE_EQ(p.orientation.w, q.w());
  EXPECT_DOUBLE_EQ(p.orientation.x, q.x());
  EXPECT_LT((to_eigen(p).matrix() - T.matrix()).norm(), 1e-12);

  // Single precision (separators): within float rounding, 0.1 mm at 1 km from the origin.
  T.translation() = Eigen::Vector3d(987.654321, -123.456789, 12.345678);
  const Eigen::Isometry3d back = to_eigen(to_msg_f(T));
  EXPECT_LT((back.translation() - T.translation()).norm(), 1e-4);
  EXPECT_LT(Eigen::AngleAxisd(back.linear().transpose() * T.linear()).angle(), 1e-6);
  EXPECT_NEAR(Eigen::Quaterniond(back.rotation()).norm(), 1.0, 1e-12);

  Matrix6d info = Matrix6d::Identity();
  info(0, 5) = info(5, 0) = 0.25;
  info(2, 3) = 7;  // row-major placement check
  cdc_msg_Information6 raw{};
  information_to_msg(info, raw);
  EXPECT_DOUBLE_EQ(raw[2 * 6 + 3], 7.0);
  EXPECT_EQ(information_to_eigen(raw), info);
}

}  // namespace
}  // namespace cdc::dds
