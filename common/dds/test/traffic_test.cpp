// The byte counting of traffic.hpp: the walk over a type's serialiser instructions gives exactly
// what Cyclone's serialiser writes, for every message type and for sequences of every length
// around the alignment boundaries.
#include "cdc/dds/traffic.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <string>
#include <utility>
#include <vector>

namespace cdc::dds {
namespace {

struct Type {
  const char* name;
  const dds_topic_descriptor_t* descriptor;
};

const std::vector<Type>& all_types() {
  static const std::vector<Type> types = {
      {"LidarPoint", &cdc_msg_LidarPoint_desc},
      {"LidarScan", &cdc_msg_LidarScan_desc},
      {"ImuSample", &cdc_msg_ImuSample_desc},
      {"ImuBatch", &cdc_msg_ImuBatch_desc},
      {"GroundTruth", &cdc_msg_GroundTruth_desc},
      {"RadioLink", &cdc_msg_RadioLink_desc},
      {"RadioState", &cdc_msg_RadioState_desc},
      {"ConsumerProgress", &cdc_msg_ConsumerProgress_desc},
      {"Odometry", &cdc_msg_Odometry_desc},
      {"Keyframe", &cdc_msg_Keyframe_desc},
      {"KeyframeCloud", &cdc_msg_KeyframeCloud_desc},
      {"Descriptor", &cdc_msg_Descriptor_desc},
      {"DescriptorSync", &cdc_msg_DescriptorSync_desc},
      {"LoopClosure", &cdc_msg_LoopClosure_desc},
      {"CloudRequest", &cdc_msg_CloudRequest_desc},
      {"CloudReply", &cdc_msg_CloudReply_desc},
      {"OptimizedPoses", &cdc_msg_OptimizedPoses_desc},
      {"SeparatorPoses", &cdc_msg_SeparatorPoses_desc},
      {"WorldTransform", &cdc_msg_WorldTransform_desc},
      {"KeyframeSequence", &cdc_msg_KeyframeSequence_desc},
      {"ModeState", &cdc_msg_ModeState_desc},
      {"RobotStatus", &cdc_msg_RobotStatus_desc},
      {"Acknowledgement", &cdc_msg_Acknowledgement_desc},
      {"Quat", &cdc_msg_Quat_desc},
      {"Pose", &cdc_msg_Pose_desc},
      {"KeyframePose", &cdc_msg_KeyframePose_desc},
      {"PointXYZI", &cdc_msg_PointXYZI_desc},
  };
  return types;
}

template <class Seq, class Elem>
void point_at(Seq& seq, std::vector<Elem>& storage) {
  seq._buffer = storage.data();
  seq._length = seq._maximum = static_cast<uint32_t>(storage.size());
  seq._release = false;
}

// The walk must handle the type and agree with the serialiser.
void expect_same_size(const dds_topic_descriptor_t* descriptor, const void* sample, const std::string& what) {
  size_t walked = 0;
  ASSERT_TRUE(walked_serialized_size(descriptor, sample, walked)) << what << ": the walk gave up";
  EXPECT_EQ(walked, serialized_size_by_writing(descriptor, sample)) << what;
  EXPECT_EQ(serialized_size(descriptor, sample), walked) << what;
  EXPECT_EQ(walked % 4, 0u) << what;
}

TEST(Traffic, EveryMessageTypeIsWalkedToItsSerialisedSize) {
  for (const Type& t : all_types()) {
    std::vector<unsigned char> zero(t.descriptor->m_size, 0);  // empty sequences, zero fields
    expect_same_size(t.descriptor, zero.data(), t.name);
  }
}

TEST(Traffic, SweepsOfEveryLengthAroundTheAlignmentAreWalkedExactly) {
  // 22 bytes per point (five floats and a ushort): each point's start moves through the 4-byte
  // alignment, so lengths 0..17 meet every case.
  for (uint32_t n = 0; n < 18; ++n) {
    std::vector<cdc_msg_LidarPoint> points(n);
    for (uint32_t i = 0; i < n; ++i) points[i] = {1.0f * static_cast<float>(i), 2, 3, 4, 5, static_cast<uint16_t>(i)};
    cdc_msg_LidarScan scan{};
    scan.point_count = n;
    point_at(scan.points, points);
    expect_same_size(&cdc_msg_LidarScan_desc, &scan, "LidarScan of " + std::to_string(n) + " points");
  }
  std::vector<cdc_msg_LidarPoint> many(28800);
  cdc_msg_LidarScan scan{};
  point_at(scan.points, many);
  expect_same_size(&cdc_msg_LidarScan_desc, &scan, "LidarScan of 28,800 points");
}

// A message of type Msg whose sequence `member` holds n (zeroed) elements.
template <class Elem, class Msg, class Seq>
void expect_same_size_with(const dds_topic_descriptor_t* descriptor, Seq Msg::*member, uint32_t n, const char* name) {
  std::vector<Elem> storage(n);
  Msg msg{};
  point_at(msg.*member, storage);
  expect_same_size(descriptor, &msg, std::string(name) + " of " + std::to_string(n));
}

TEST(Traffic, MessagesWithSequencesAreWalkedExactly) {
  for (uint32_t n : {0u, 1u, 2u, 3u, 5u, 7u, 64u}) {
    expect_same_size_with<cdc_msg_ImuSample>(&cdc_msg_ImuBatch_desc, &cdc_msg_ImuBatch::samples, n, "ImuBatch");
    expect_same_size_with<cdc_msg_RadioLink>(&cdc_msg_RadioState_desc, &cdc_msg_RadioState::links, n, "RadioState");
    expect_same_size_with<cdc_msg_PointXYZI>(&cdc_msg_Keyframe_desc, &cdc_msg_Keyframe::cloud, n, "Keyframe");
    expect_same_size_with<uint8_t>(&cdc_msg_CloudReply_desc, &cdc_msg_CloudReply::packed_points, n, "CloudReply");
    expect_same_size_with<uint8_t>(&cdc_msg_KeyframeCloud_desc, &cdc_msg_KeyframeCloud::packed_points, n,
                                   "KeyframeCloud");
    expect_same_size_with<cdc_msg_KeyframePose>(&cdc_msg_OptimizedPoses_desc, &cdc_msg_OptimizedPoses::poses, n,
                                                "OptimizedPoses");
    expect_same_size_with<cdc_msg_KeyframePoseF>(&cdc_msg_SeparatorPoses_desc, &cdc_msg_SeparatorPoses::poses, n,
                                                 "SeparatorPoses");
    expect_same_size_with<cdc_msg_LoopClosure>(&cdc_msg_SeparatorPoses_desc, &cdc_msg_SeparatorPoses::loops, n,
                                               "SeparatorPoses with relayed loops");
    // A sequence of bytes whose odd length needs the payload padded before the struct after it.
    std::vector<uint8_t> cells(n * 3 + 1);
    cdc_msg_Descriptor descriptor{};
    point_at(descriptor.packed_cells, cells);
    expect_same_size(&cdc_msg_Descriptor_desc, &descriptor, "Descriptor of " + std::to_string(n));
  }
}

}  // namespace
}  // namespace cdc::dds
