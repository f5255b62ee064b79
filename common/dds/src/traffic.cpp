#include "cdc/dds/traffic.hpp"

#include <dds/ddsi/ddsi_cdrstream.h>

#include <memory>
#include <mutex>

namespace cdc::dds {
namespace {

struct Registry {
  std::mutex mutex;
  std::map<std::pair<uint32_t, std::string>, std::unique_ptr<TopicCounters>> topics;
};

Registry& registry() {
  static Registry r;
  return r;
}

}  // namespace

TopicCounters& topic_counters(uint32_t domain, const std::string& topic) {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  auto& slot = r.topics[{domain, topic}];
  if (!slot) slot = std::make_unique<TopicCounters>();
  return *slot;
}

std::map<std::pair<uint32_t, std::string>, TopicTotals> topic_traffic() {
  Registry& r = registry();
  const std::lock_guard<std::mutex> lock(r.mutex);
  std::map<std::pair<uint32_t, std::string>, TopicTotals> out;
  for (const auto& [key, c] : r.topics) {
    out[key] = {c->samples_written.load(), c->bytes_written.load(), c->samples_taken.load(), c->bytes_taken.load()};
  }
  return out;
}

size_t serialized_size(const dds_topic_descriptor_t* descriptor, const void* sample) {
  constexpr size_t kEncapsulation = 4;
  constexpr uint32_t kXcdr1 = 1;  // CDR_ENC_VERSION_1 (dds/ddsi/q_protocol.h)
  dds_ostream_t os;
  dds_ostream_init(&os, 0, kXcdr1);
  dds_stream_write(&os, static_cast<const char*>(sample), descriptor->m_ops);
  const size_t n = os.m_index;
  dds_ostream_fini(&os);
  return kEncapsulation + n;
}

}  // namespace cdc::dds
