// The peer optimiser's messages and PeerCore's types, both ways: what comes in, converted for the
// core; what goes out, built from its state and output. No DDS entities here: the node writes them.
#pragma once

#include "cdc/dds/compact.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/peer_optimiser/peer_core.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

namespace cdc::peer {

using KeyframePoses = std::vector<std::pair<uint32_t, Eigen::Isometry3d>>;

// The back-end mode and switch reason as the mode and status messages carry them, and back.
cdc_msg_BackendMode to_msg(Mode mode);
cdc_msg_SwitchReason to_msg(SwitchReason reason);
Mode from_msg(cdc_msg_BackendMode mode);

// In (validated messages).
OwnKeyframe own_keyframe(const cdc_msg_Keyframe& m);
LoopRecord loop_record(const cdc_msg_LoopClosure& m);
CentralResult central_result(const cdc_msg_OptimizedPoses& m);
AckIn ack_in(const cdc_msg_Acknowledgement& m);
// What a peer sent this robot: its separator poses, the loops it relays, its count of inter-robot loops.
SeparatorOut separator_in(const cdc_msg_SeparatorPoses& m);

// Out: the robot that writes, its incarnation, and the message's wall-clock stamp.
struct Origin {
  uint32_t robot = 0;
  uint32_t incarnation = 0;
  int64_t stamp_ns = 0;
};

// distance: the one the switch was decided on; nullopt when unknown.
cdc_msg_ModeState mode_state(const Origin& o, Mode mode, SwitchReason reason, std::optional<double> distance,
                             uint32_t transitions);
// The robot's own T_world_robot for the central (a distributed estimate, on rejoining).
cdc_msg_WorldTransform world_transform(const Origin& o, const Eigen::Isometry3d& T_world_robot, uint64_t rounds);
// The position in W a status carries; nullopt when its sender knows no world yet (world_valid false).
std::optional<Eigen::Vector3d> status_position(const cdc_msg_RobotStatus& m);

// The robot's status on the radio: its pose in W for its peers' range checks, and its mode.
cdc_msg_RobotStatus robot_status(const Origin& o, const std::optional<Eigen::Isometry3d>& T_world_base,
                                 int64_t last_keyframe_id, Mode mode);
// The messages below borrow `storage` for their poses: it must outlive the write.
struct SeparatorStorage {
  std::vector<cdc_msg_KeyframePoseF> poses;
  std::vector<cdc_msg_LoopClosure> loops;
};
cdc_msg_SeparatorPoses separator_message(const Origin& o, const SeparatorOut& s, uint32_t round,
                                         SeparatorStorage& storage);
// A loop as the core holds it, for relaying (its stamp and fitness are not kept: both 0).
cdc_msg_LoopClosure loop_message(const LoopRecord& l);
// An own keyframe as the core holds it, for the central: no cloud (point_count 0), which crosses the
// radio apart, packed (keyframe_cloud_message).
cdc_msg_Keyframe keyframe_message(uint32_t robot, const OwnKeyframe& k);
// An own keyframe's packed cloud for the central's map; borrows `packed`'s bytes: they must outlive
// the write.
cdc_msg_KeyframeCloud keyframe_cloud_message(uint32_t robot, const OwnKeyframe& k, dds::compact::PackedCloud& packed);
// Where the robot's keyframe sequence stands: its newest keyframe (nullptr: none held yet).
cdc_msg_KeyframeSequence keyframe_sequence(uint32_t robot, const OwnKeyframe* newest);
// version: the correction's number (graph_version), counted by the node.
cdc_msg_OptimizedPoses correction_message(const Origin& o, const Correction& c, uint64_t version,
                                          std::vector<cdc_msg_KeyframePose>& storage);

}  // namespace cdc::peer
