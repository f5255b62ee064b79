// This process's per-topic traffic (traffic.hpp) as JSON for the services' --stats-out files:
// {"<domain>": {"<topic>": {"samples_written", "bytes_written", "samples_taken", "bytes_taken",
// "undecodable", "samples_lost", "samples_rejected"}}}.
#pragma once

#include "cdc/dds/traffic.hpp"

#include <nlohmann/json.hpp>

#include <string>

namespace cdc::dds {

inline nlohmann::json topic_traffic_json() {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [key, t] : topic_traffic()) {
    j[std::to_string(key.first)][key.second] = {
        {"samples_written", t.samples_written},  {"bytes_written", t.bytes_written}, {"samples_taken", t.samples_taken},
        {"bytes_taken", t.bytes_taken},          {"undecodable", t.undecodable},     {"samples_lost", t.samples_lost},
        {"samples_rejected", t.samples_rejected}};
  }
  return j;
}

}  // namespace cdc::dds
