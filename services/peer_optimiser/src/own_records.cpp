#include "own_records.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/peer_optimiser/peer_core.hpp"

namespace cdc::peer {

void OwnRecords::keep(const cdc_msg_Keyframe& m) {
  Keyframe& k = keyframes_[m.keyframe_id];
  k.msg = m;
  k.cloud.assign(m.cloud._buffer, m.cloud._buffer + m.cloud._length);
  k.msg.cloud = {};
}

void OwnRecords::keep(const cdc_msg_LoopClosure& m) { loops_[m.loop_seq] = m; }

std::optional<cdc_msg_Keyframe> OwnRecords::keyframe(uint32_t id) {
  auto it = keyframes_.find(id);
  if (it == keyframes_.end()) return std::nullopt;
  cdc_msg_Keyframe m = it->second.msg;
  dds::borrow(m.cloud, it->second.cloud);
  return m;
}

const cdc_msg_LoopClosure* OwnRecords::loop(uint32_t seq) const {
  auto it = loops_.find(seq);
  return it == loops_.end() ? nullptr : &it->second;
}

void OwnRecords::corrected(uint32_t id, const Eigen::Isometry3d& T_world_keyframe) {
  corrected_[id] = T_world_keyframe;
}

geometry::Trajectory OwnRecords::world_trajectory() const {
  std::map<uint32_t, Eigen::Isometry3d> T_odom;
  for (const auto& [id, k] : keyframes_) T_odom[id] = dds::to_eigen(k.msg.T_odom_keyframe);
  geometry::Trajectory trajectory;
  for (const auto& [id, T] : complete_world_poses(T_odom, corrected_)) {
    trajectory.push_back({keyframes_.at(id).msg.stamp_ns, T});
  }
  return trajectory;
}

}  // namespace cdc::peer
