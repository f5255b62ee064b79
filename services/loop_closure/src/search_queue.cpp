#include "cdc/loop_closure/search_queue.hpp"

#include <algorithm>
#include <chrono>

namespace cdc::loops {

void SearchQueue::push(DescriptorIn d, Nanos now) {
  arrived_.emplace(std::make_pair(d.robot, d.id), now);
  queues_[d.robot].push_back(std::move(d));
  ++size_;
}

std::optional<DescriptorIn> SearchQueue::pop() {
  if (size_ == 0) return std::nullopt;
  // The first non-empty queue after the last robot served, wrapping around.
  auto it = last_served_ ? queues_.upper_bound(*last_served_) : queues_.begin();
  for (size_t n = 0; n <= queues_.size(); ++n, ++it) {
    if (it == queues_.end()) it = queues_.begin();
    if (!it->second.empty()) break;
  }
  DescriptorIn d = std::move(it->second.front());
  it->second.pop_front();
  last_served_ = it->first;
  --size_;
  return d;
}

size_t SearchQueue::size(uint32_t robot) const {
  const auto it = queues_.find(robot);
  return it == queues_.end() ? 0 : it->second.size();
}

std::optional<double> SearchQueue::latency_s(const LoopOut& loop, Nanos now) const {
  const auto a = arrived_.find({loop.robot_a, loop.keyframe_a});
  const auto b = arrived_.find({loop.robot_b, loop.keyframe_b});
  if (a == arrived_.end() || b == arrived_.end()) return std::nullopt;
  return std::chrono::duration<double>(now - std::max(a->second, b->second)).count();
}

}  // namespace cdc::loops
