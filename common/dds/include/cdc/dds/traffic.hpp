// Per-topic traffic of this process: samples and serialised payload bytes (XCDR1, as they go on
// the wire before RTPS headers) written and taken on every topic, counted by Writer::write and
// Reader::take (a reader counts the size of the serialised data it received; samples Cyclone
// delivered but could not deserialise count as undecodable, samples its readers lost or refused as
// samples_lost and samples_rejected). A sample written once counts once
// here however many readers it reaches; the bytes on each link are counted at the IP level by
// cdc-launch.
#pragma once

#include "cdc/dds/types.hpp"

#include <atomic>
#include <cstdint>
#include <map>
#include <string>
#include <string_view>
#include <utility>

namespace cdc::dds {

struct TopicCounters {
  std::atomic<uint64_t> samples_written{0}, bytes_written{0}, samples_taken{0}, bytes_taken{0};
  std::atomic<uint64_t> undecodable{0};  // samples taken that Cyclone could not deserialise (dropped)
  // Samples this process's readers never got: lost on the way (SAMPLE_LOST) or refused by a reader's
  // resource limits (SAMPLE_REJECTED); see Reader::losses.
  std::atomic<uint64_t> samples_lost{0}, samples_rejected{0};
};

struct TopicTotals {
  uint64_t samples_written = 0, bytes_written = 0, samples_taken = 0, bytes_taken = 0, undecodable = 0;
  uint64_t samples_lost = 0, samples_rejected = 0;
};

// The process-wide counters of `topic` on `domain` (created on first use; the reference stays valid).
TopicCounters& topic_counters(uint32_t domain, const std::string& topic);

// A sample Cyclone receives but cannot deserialise (an enum value out of range, a sequence longer than its
// bound or its data) is dropped before any reader sees it: no take and no status reports it, only a warning in
// Cyclone's log naming the topic. Installs, once per process, a log sink that counts each such warning as
// undecodable on its topic and writes every message to stderr as Cyclone's own sink does. Participant's
// constructor calls it.
void watch_undecodable_samples();

// One message as Cyclone's log gives it (without its header): counts it when it reports a sample that could
// not be deserialised, and says whether it did.
bool count_undecodable_message(uint32_t domain, std::string_view message);

// Every (domain, topic) this process has opened a writer or reader for, with its totals.
std::map<std::pair<uint32_t, std::string>, TopicTotals> topic_traffic();

// Serialised size of one sample of the type `descriptor` describes, as Cyclone sends it: 4 bytes
// of encapsulation header plus its XCDR1 body padded to a multiple of 4 bytes.
// Walks the type's serialiser instructions rather than serialising the sample (a sweep of 28,800
// points costs microseconds instead of most of a millisecond); types it cannot walk are serialised.
size_t serialized_size(const dds_topic_descriptor_t* descriptor, const void* sample);

// The same figure, always by serialising the sample (the reference the walk is tested against).
size_t serialized_size_by_writing(const dds_topic_descriptor_t* descriptor, const void* sample);

// The walk alone: false (size untouched) when the type holds instructions it does not walk.
bool walked_serialized_size(const dds_topic_descriptor_t* descriptor, const void* sample, size_t& size);

template <class T>
size_t serialized_size(const T& sample) {
  return serialized_size(TypeSupport<T>::descriptor(), &sample);
}

}  // namespace cdc::dds
