// Topic names of cdc-slam: the one place they are spelled. Pattern cdc/<area>/<name>.
#pragma once

namespace cdc::dds::topics {

inline constexpr const char* kLidar = "cdc/sensor/lidar";
inline constexpr const char* kImu = "cdc/sensor/imu";
inline constexpr const char* kOdometry = "cdc/frontend/odometry";
inline constexpr const char* kKeyframe = "cdc/frontend/keyframe";
// A keyframe's packed cloud on the radio, for the central's map.
inline constexpr const char* kKeyframeCloud = "cdc/map/keyframe_cloud";
inline constexpr const char* kDescriptor = "cdc/place/descriptor";
inline constexpr const char* kDescriptorSync = "cdc/place/descriptor_sync";
inline constexpr const char* kLoopClosure = "cdc/loop/closure";
inline constexpr const char* kCloudRequest = "cdc/loop/cloud_request";
inline constexpr const char* kCloudReply = "cdc/loop/cloud_reply";
inline constexpr const char* kCentralOptimized = "cdc/central/optimized";
inline constexpr const char* kCentralAck = "cdc/central/ack";
// The central optimiser's liveliness (MANUAL_BY_TOPIC) with its status: what the robots' mode switch watches.
inline constexpr const char* kCentralAlive = "cdc/central/alive";
inline constexpr const char* kCorrection = "cdc/backend/correction";
// The newest keyframe the peer optimiser holds: where a restarted front-end continues.
inline constexpr const char* kKeyframeSequence = "cdc/backend/sequence";
inline constexpr const char* kMode = "cdc/backend/mode";
inline constexpr const char* kSeparator = "cdc/peer/separator";
inline constexpr const char* kWorldTransform = "cdc/peer/world_transform";
inline constexpr const char* kRobotStatus = "cdc/status/robot";
inline constexpr const char* kGroundTruth = "cdc/sim/ground_truth";
inline constexpr const char* kRadio = "cdc/sim/radio";
inline constexpr const char* kProgress = "cdc/sim/progress";

}  // namespace cdc::dds::topics
