// Watches the liveliness of the writers of one topic and reports alive/lost transitions.
#pragma once

#include "cdc/dds/entity.hpp"
#include "cdc/dds/participant.hpp"

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <mutex>
#include <optional>
#include <string>

namespace cdc::dds {

class GuardCondition;

enum class Liveliness { kUnknown, kAlive, kLost };
const char* to_string(Liveliness state) noexcept;

struct LivelinessEvent {
  Liveliness state = Liveliness::kUnknown;     // kAlive or kLost
  std::chrono::steady_clock::time_point when;  // when Cyclone reported it
  int64_t wall_time_ns = 0;                    // the same instant, system clock [ns]
  int32_t alive_writers = 0;                   // writers alive after the change
};

// Creates its own reader on `topic` (QoS qos::monitored_reader) with a liveliness listener.
// The listener only records; consumers poll events or wait for them on their own thread.
class LivelinessMonitor {
 public:
  LivelinessMonitor(const Participant& participant, dds_entity_t topic, std::string name);
  ~LivelinessMonitor();
  LivelinessMonitor(const LivelinessMonitor&) = delete;
  LivelinessMonitor& operator=(const LivelinessMonitor&) = delete;

  // kUnknown until the first writer is seen, then kAlive or kLost.
  Liveliness state() const;

  // The next transition not yet consumed, waiting up to timeout for one.
  std::optional<LivelinessEvent> next_event(std::chrono::milliseconds timeout);

  // Waits until the state is `wanted` (consuming events on the way); returns the event
  // that made it so, or nullopt on timeout. An already current state returns at once
  // with the last transition.
  std::optional<LivelinessEvent> wait_for(Liveliness wanted, std::chrono::milliseconds timeout);

  // Triggered on every transition (may be null). Must outlive the monitor or be cleared.
  void set_notify(GuardCondition* guard);

  const std::string& name() const noexcept { return name_; }

  // Called by Cyclone's listener thread; public only for the C callback.
  void on_liveliness_changed(int32_t alive_count);

 private:
  std::string name_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<LivelinessEvent> events_;
  Liveliness state_ = Liveliness::kUnknown;
  std::optional<LivelinessEvent> last_;
  GuardCondition* notify_ = nullptr;
  Entity reader_;  // last member: deleted first, so no callback sees a half-destroyed monitor
};

}  // namespace cdc::dds
