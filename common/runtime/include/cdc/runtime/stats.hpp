// A service's counters, written once at shutdown as one JSON document: the node's own counters (a
// struct with nlohmann's to_json, e.g. NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE), the samples its boundary
// refused by topic, and this process's traffic per topic.
#pragma once

#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <string>
#include <utility>

namespace cdc::runtime {

// own + {"rejected": {topic: n}, "rejected_samples": n, "topics": traffic}.
nlohmann::json service_stats(nlohmann::json own, const Boundary& boundary);

// Writes service_stats to path (nothing when path is empty). Throws std::runtime_error naming the
// file when it cannot be written.
void write_stats(const std::string& path, nlohmann::json own, const Boundary& boundary);

template <class Stats>
void write_stats(const std::string& path, const Stats& own, const Boundary& boundary) {
  write_stats(path, nlohmann::json(own), boundary);
}

// The same for a service: to its --stats-out, with its boundary's refusals.
inline void write_stats(const Service& service, nlohmann::json own) {
  write_stats(service.options().stats_out, std::move(own), service.boundary());
}

}  // namespace cdc::runtime
