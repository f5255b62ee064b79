// report.md and the mode timeline (modes.svg) of a run, rendered from its gathered results.
#pragma once

#include "report.hpp"
#include "report_results.hpp"

#include <nlohmann/json.hpp>

#include <optional>
#include <string>
#include <vector>

namespace cdc::launch {

// robots: in the order of info.robots; traffic: netns runs only; topics: topic_traffic()'s table.
std::string render_markdown(const RunInfo& info, const std::vector<RobotResult>& robots,
                            const std::optional<TrafficSummary>& traffic, const nlohmann::json& topics);

// Mode over sim time, one row per robot, with the periods its link to the central was cut.
std::string render_timeline(const RunInfo& info, const std::vector<RobotResult>& robots);

}  // namespace cdc::launch
