// The robot's own keyframes (each with its cloud) and loop closures as they came in, and where the
// corrections last put its keyframes: what the node re-sends to a central that lacks them, and the
// trajectory it writes at shutdown.
#pragma once

#include "cdc/dds/types.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

namespace cdc::peer {

class OwnRecords {
 public:
  // Copies the message and its cloud (a reader lends its samples only while they are handled);
  // a keyframe or loop already held under the same id or sequence number is replaced.
  void keep(const cdc_msg_Keyframe& m);
  void keep(const cdc_msg_LoopClosure& m);

  // The keyframe as it came in, its cloud lent from here (until it is kept again); nullopt when
  // none of that id is held.
  std::optional<cdc_msg_Keyframe> keyframe(uint32_t id);
  const cdc_msg_LoopClosure* loop(uint32_t seq) const;
  size_t keyframes() const noexcept { return keyframes_.size(); }

  // A published correction placed own keyframe `id` at T_world_keyframe.
  void corrected(uint32_t id, const Eigen::Isometry3d& T_world_keyframe);
  // Every own keyframe in W at its stamp: as last corrected, else placed by its odometry relative
  // to a corrected one (complete_world_poses).
  geometry::Trajectory world_trajectory() const;

 private:
  struct Keyframe {
    cdc_msg_Keyframe msg{};  // cloud detached
    std::vector<cdc_msg_PointXYZI> cloud;
  };
  std::map<uint32_t, Keyframe> keyframes_;
  std::map<uint32_t, cdc_msg_LoopClosure> loops_;
  std::map<uint32_t, Eigen::Isometry3d> corrected_;
};

}  // namespace cdc::peer
