// Named QoS profiles, one per purpose. Every entity of cdc-slam gets its QoS from here.
#pragma once

#include <dds/dds.h>

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

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
  // DDS partitions (wildcards allowed on readers). A partition is a publisher/subscriber policy:
  // Writer and Reader create their own publisher/subscriber carrying it. Writers and readers match
  // only when their partitions do, and Cyclone sends nothing to readers that do not match.
  Qos& partitions(const std::vector<std::string>& names);
  std::vector<std::string> partitions() const;

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

// Partition names: the one place they are spelled. Data meant for one robot's own services
// (keyframes with their clouds, corrections, cloud replies) is written in that robot's partition,
// so that it never crosses the radio to other robots. Readers of such data also accept the
// default partition (tools and tests that do not partition).
namespace partitions {
std::string robot(uint32_t robot_id);                    // "robot/<id>"
inline const char* const kAllRobots = "robot/*";         // the central node's readers
std::vector<std::string> own_reader(uint32_t robot_id);  // {"robot/<id>", ""}
std::vector<std::string> all_robots_reader();            // {"robot/*", ""}
}  // namespace partitions
}  // namespace cdc::dds
