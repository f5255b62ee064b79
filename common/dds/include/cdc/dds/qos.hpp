// Named QoS profiles, one per purpose. Every entity of cdc-slam gets its QoS from here.
#pragma once

#include <dds/dds.h>

#include <chrono>
#include <cstdint>

namespace cdc::dds {

// Owner of a dds_qos_t.
class Qos {
 public:
  Qos();
  ~Qos();
  Qos(const Qos& other);
  Qos& operator=(const Qos& other);
  Qos(Qos&& other) noexcept;
  Qos& operator=(Qos&& other) noexcept;

  const dds_qos_t* get() const noexcept { return qos_; }
  dds_qos_t* get() noexcept { return qos_; }

  Qos& reliable(std::chrono::milliseconds max_blocking = std::chrono::milliseconds(500));
  Qos& best_effort();
  Qos& keep_last(int32_t depth);
  Qos& keep_all();
  Qos& transient_local();
  Qos& volatile_durability();
  Qos& liveliness_manual_by_topic(std::chrono::nanoseconds lease);
  Qos& liveliness_automatic(std::chrono::nanoseconds lease);

 private:
  dds_qos_t* qos_;
};

namespace qos {

// Sensor streams (LiDAR, IMU): newest data matters. Best effort by default; reliable when a
// consumer must see every sample (lock-step playback).
Qos sensor_stream(int32_t depth = 10, bool reliable = false);

// Keyed state (keyframes, poses, mode, acknowledgements): reliable, transient-local, the last
// `depth` samples per instance, so a late joiner gets the current state.
Qos keyed_state(int32_t depth = 1);

// Event streams (loop closures, requests, replies): reliable, volatile, deep history.
Qos event_stream(int32_t depth = 256);

// A writer whose liveliness others monitor: MANUAL_BY_TOPIC with the given lease, asserted by
// the application (Writer::assert_liveliness or any write), plus keyed_state semantics.
Qos monitored_writer(std::chrono::nanoseconds lease);

// The matching reader side: reliable, transient-local, accepts any offered lease.
Qos monitored_reader();

}  // namespace qos
}  // namespace cdc::dds
