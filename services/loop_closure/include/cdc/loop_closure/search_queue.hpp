// The descriptors waiting to be searched, one queue per robot, served in turn. A peer that comes
// back in range delivers its backlog (hundreds of descriptors) at once; searched in arrival order,
// it held back this robot's own new keyframes, and so the loops a real-time correction needs, by as
// long as the whole backlog took to search and verify. Each robot's descriptors keep their keyframe
// order (the sequencer's). It also remembers when each descriptor came in, so that the service can
// say how long its loops took from the later keyframe's descriptor to publication. Synchronous, no DDS.
#pragma once

#include "cdc/loop_closure/loop_core.hpp"

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <utility>

namespace cdc::loops {

class SearchQueue {
 public:
  void push(DescriptorIn d, Nanos now);
  // The next descriptor of the robot after the last one served (by robot id, wrapping around).
  std::optional<DescriptorIn> pop();
  size_t size() const noexcept { return size_; }
  bool empty() const noexcept { return size_ == 0; }
  size_t size(uint32_t robot) const;

  // Seconds from the later of the loop's two descriptors coming in to `now`; nullopt when either
  // was never queued here.
  std::optional<double> latency_s(const LoopOut& loop, Nanos now) const;

 private:
  std::map<uint32_t, std::deque<DescriptorIn>> queues_;
  std::optional<uint32_t> last_served_;
  size_t size_ = 0;
  std::map<std::pair<uint32_t, uint32_t>, Nanos> arrived_;  // (robot, keyframe) -> when queued
};

}  // namespace cdc::loops
