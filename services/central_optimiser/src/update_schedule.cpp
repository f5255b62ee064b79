#include "cdc/central_optimiser/update_schedule.hpp"

namespace cdc::central {

UpdateSchedule::UpdateSchedule(std::chrono::milliseconds update_period, std::chrono::milliseconds max_result_age)
    : period_(update_period),
      max_age_(max_result_age),
      last_update_(Clock::now() - std::chrono::hours(1)),
      last_results_(last_update_) {}

bool UpdateSchedule::update_due(bool dirty, bool settled, Clock::time_point now) const {
  return (dirty || !settled) && now - last_update_ >= period_;
}

bool UpdateSchedule::updated(bool settled, Clock::time_point now) {
  last_update_ = now;
  ++updates_;
  if (!settled) ++unsettled_;
  if (!settled && now - last_results_ < max_age_) {
    ++held_;
    return false;
  }
  last_results_ = now;
  return true;
}

ResultPacer::ResultPacer(size_t robots, double poses_per_second) : turns_(robots), rate_(poses_per_second) {}

void ResultPacer::updated() {
  for (Turn& t : turns_) {
    if (t.pending) ++merged_;
    t.pending = true;
  }
}

bool ResultPacer::due(uint32_t robot, Clock::time_point now) const {
  return robot < turns_.size() && turns_[robot].pending && now >= turns_[robot].next;
}

void ResultPacer::sent(uint32_t robot, size_t poses, Clock::time_point now) {
  if (robot >= turns_.size()) return;
  Turn& t = turns_[robot];
  t.pending = false;
  if (rate_ > 0.0) {
    t.next = now + std::chrono::duration_cast<Clock::duration>(
                       std::chrono::duration<double>(static_cast<double>(poses) / rate_));
  }
}

}  // namespace cdc::central
