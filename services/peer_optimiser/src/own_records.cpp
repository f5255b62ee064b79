#include "own_records.hpp"

namespace cdc::peer {

dds::compact::PackedCloud& OwnRecords::keep_cloud(const cdc_msg_Keyframe& m, float resolution_m) {
  auto it = clouds_.find(m.keyframe_id);
  if (it != clouds_.end()) return it->second;
  points_.clear();
  for (uint32_t i = 0; i < m.cloud._length; ++i) {
    const cdc_msg_PointXYZI& p = m.cloud._buffer[i];
    points_.emplace_back(p.x, p.y, p.z);
  }
  return clouds_.emplace(m.keyframe_id, dds::compact::pack_points(points_, resolution_m)).first->second;
}

void OwnRecords::keep(const cdc_msg_LoopClosure& m) { loops_[m.loop_seq] = m; }

dds::compact::PackedCloud* OwnRecords::cloud(uint32_t id) {
  auto it = clouds_.find(id);
  return it == clouds_.end() ? nullptr : &it->second;
}

const cdc_msg_LoopClosure* OwnRecords::loop(uint32_t seq) const {
  auto it = loops_.find(seq);
  return it == loops_.end() ? nullptr : &it->second;
}

}  // namespace cdc::peer
