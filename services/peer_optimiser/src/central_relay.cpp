#include "cdc/peer_optimiser/central_relay.hpp"

#include <algorithm>

namespace cdc::peer {

std::optional<uint32_t> CentralRelay::placed_newest() const {
  std::optional<uint32_t> newest;
  if (last_ && !last_->from_hint) {
    for (const auto& p : last_->poses) newest = std::max(newest.value_or(0), p.first);
  }
  return newest;
}

bool CentralRelay::update() {
  const std::optional<uint32_t> newest = placed_newest();
  if (!frontier_ && newest && relayed_newest_ && *newest < *relayed_newest_) {
    frontier_ = *relayed_newest_;  // behind a result already relayed
  }
  if (frontier_ && newest && *newest >= *frontier_) {
    frontier_.reset();  // caught up
  }
  const bool current = last_.has_value() && !last_->from_hint && !frontier_;
  if (current && newest) {
    relayed_newest_ = std::max(relayed_newest_.value_or(0), *newest);
  }
  return current;
}

}  // namespace cdc::peer
