// Per-topic traffic of this process: samples and serialised payload bytes (XCDR1, as they go on
// the wire before RTPS headers) written and taken on every topic, counted by Writer::write and
// Reader::take. A sample written once counts once here however many readers it reaches; the
// bytes on each link are counted at the IP level by cdc-launch.
#pragma once

#include "cdc/dds/types.hpp"

#include <atomic>
#include <cstdint>
#include <map>
#include <string>
#include <utility>

namespace cdc::dds {

struct TopicCounters {
  std::atomic<uint64_t> samples_written{0}, bytes_written{0}, samples_taken{0}, bytes_taken{0};
};

struct TopicTotals {
  uint64_t samples_written = 0, bytes_written = 0, samples_taken = 0, bytes_taken = 0;
};

// The process-wide counters of `topic` on `domain` (created on first use; the reference stays valid).
TopicCounters& topic_counters(uint32_t domain, const std::string& topic);

// Every (domain, topic) this process has opened a writer or reader for, with its totals.
std::map<std::pair<uint32_t, std::string>, TopicTotals> topic_traffic();

// Serialised size of one sample of the type `descriptor` describes: 4 bytes of encapsulation
// header plus its XCDR1 body.
size_t serialized_size(const dds_topic_descriptor_t* descriptor, const void* sample);

template <class T>
size_t serialized_size(const T& sample) {
  return serialized_size(TypeSupport<T>::descriptor(), &sample);
}

}  // namespace cdc::dds
