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

}  // namespace cdc::central
