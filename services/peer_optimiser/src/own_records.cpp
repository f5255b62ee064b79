#include "own_records.hpp"

namespace cdc::peer {

void OwnRecords::keep_cloud(const cdc_msg_Keyframe& m) {
  clouds_.try_emplace(m.keyframe_id, m.cloud._buffer, m.cloud._buffer + m.cloud._length);
}

void OwnRecords::keep(const cdc_msg_LoopClosure& m) { loops_[m.loop_seq] = m; }

std::vector<cdc_msg_PointXYZI>* OwnRecords::cloud(uint32_t id) {
  auto it = clouds_.find(id);
  return it == clouds_.end() ? nullptr : &it->second;
}

const cdc_msg_LoopClosure* OwnRecords::loop(uint32_t seq) const {
  auto it = loops_.find(seq);
  return it == loops_.end() ? nullptr : &it->second;
}

}  // namespace cdc::peer
