// Something a node does every `period` (re-publish a state, write a status): due once the period
// has passed since it was last done, and at once when it never was or was expired.
#pragma once

#include <chrono>
#include <optional>

namespace cdc::peer {

class Period {
 public:
  using Clock = std::chrono::steady_clock;

  explicit Period(std::chrono::milliseconds period) : period_(period) {}
  bool due(Clock::time_point now) const { return !last_ || now - *last_ >= period_; }
  void done(Clock::time_point now) { last_ = now; }
  void expire() { last_.reset(); }

 private:
  std::chrono::milliseconds period_;
  std::optional<Clock::time_point> last_;
};

}  // namespace cdc::peer
