#include "rendezvous.hpp"

#include <algorithm>

namespace cdc::launch {

bool Rendezvous::update(std::vector<uint32_t> not_rejoined, std::vector<uint32_t> busy, Clock::time_point now) {
  if (not_rejoined.empty() && !all_rejoined_) all_rejoined_at_ = now;
  all_rejoined_ = not_rejoined.empty();
  if (busy.empty() && !caught_up_) caught_up_at_ = now;
  caught_up_ = busy.empty();
  not_rejoined_ = std::move(not_rejoined);
  busy_ = std::move(busy);
  const bool settled = all_rejoined_ && caught_up_ && now - std::max(all_rejoined_at_, caught_up_at_) >= settle_;
  if (!settled && now < start_ + limit_) return false;
  ended_at_ = now;
  return true;
}

double Rendezvous::waited_s() const {
  return std::chrono::duration<double>((all_rejoined_ ? all_rejoined_at_ : ended_at_) - start_).count();
}

std::optional<double> Rendezvous::caught_up_s() const {
  if (!caught_up_) return std::nullopt;
  return std::chrono::duration<double>(caught_up_at_ - start_).count();
}

}  // namespace cdc::launch
