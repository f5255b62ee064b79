#include "written_loops.hpp"

namespace cdc::loops {

void WrittenLoops::wrote(const cdc_msg_LoopClosure& m, bool withdrawal, Nanos now) {
  const uint64_t id = next_++;
  loops_[id] = m;
  if (const auto gone = reach_->published(id, m.robot_a, m.keyframe_a, m.robot_b, m.keyframe_b, withdrawal, now)) {
    loops_.erase(*gone);
  }
}

std::vector<const cdc_msg_LoopClosure*> WrittenLoops::due(Nanos now) {
  std::vector<const cdc_msg_LoopClosure*> out;
  for (uint64_t id : reach_->due(now)) out.push_back(&loops_.at(id));
  return out;
}

}  // namespace cdc::loops
