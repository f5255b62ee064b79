// What a run's report is made of, gathered before anything is written: each robot's results (its
// trajectories against ground truth, its mode transitions, its services' stats) and the traffic
// figures per link and mode. report.cpp turns them into report.json, report_render.cpp into
// report.md and the mode timeline.
#pragma once

#include "network.hpp"
#include "report.hpp"

#include "cdc/eval/evaluation.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cdc::launch {

// One line of a peer optimiser's modes.csv.
struct Transition {
  int64_t wall_ns = 0, sim_ns = 0;
  std::string from, to, reason;
};

// One of a robot's trajectories against its ground truth: the evaluation, or why there is none.
struct TrajectoryResult {
  std::optional<eval::Evaluation> evaluation;
  std::string error;            // set when there is no evaluation
  std::optional<size_t> poses;  // with "too few poses": how many the estimate has

  double ate_pct_of_length() const;
  nlohmann::json to_json(const eval::EvalOptions& options) const;
};

struct ModeSwitches {
  size_t to_distributed = 0, to_centralized = 0, on_liveliness_lost = 0;
};

struct RobotResult {
  uint32_t robot = 0;
  bool keyframes_from_central = false;  // the central's final graph holds the robot (else: its peer optimiser's)
  TrajectoryResult odometry, keyframes;
  std::vector<Transition> transitions;
  ModeSwitches switches;
  std::vector<eval::SvgMarker> markers;  // where the robot switched, on its ground truth
  nlohmann::json stats;                  // service -> its stats file's content; null when there is none

  // report.json's entry of the robot, without its traffic.
  nlohmann::json to_json(const eval::EvalOptions& options) const;
};

// The central's final graph as one trajectory per robot it (nearly) wholly holds.
std::map<uint32_t, geometry::Trajectory> central_trajectories(const std::filesystem::path& g2o,
                                                              const std::filesystem::path& run,
                                                              const std::vector<uint32_t>& robots);

// Robot `robot`'s results from the run folder; writes on the way its keyframes in the central's graph
// (keyframes_central.tum) and every trajectory in KITTI format. `index`: the robot's place in the run,
// which gives its colour in the plots.
RobotResult gather_robot(const RunInfo& info, uint32_t robot, size_t index,
                         const std::map<uint32_t, geometry::Trajectory>& central, const eval::EvalOptions& options);

// The bytes one robot counted on one link while in one mode, and the keyframes made meanwhile.
struct LinkModeTraffic {
  uint32_t robot = 0, peer = 0;
  std::string mode;
  LinkBytes bytes;
  uint64_t keyframes_in_mode = 0;    // the robot's own
  uint64_t keyframes_both_ends = 0;  // its own and, for a robot peer, the peer's (the central makes none)

  std::optional<double> sent_per_keyframe() const;             // user data sent per own keyframe
  std::optional<double> bytes_per_keyframe() const;            // sent and received per own keyframe
  std::optional<double> bytes_per_keyframe_both_ends() const;  // sent and received per keyframe of either end
  nlohmann::json to_json() const;
};

// Whole run, one robot-to-robot link, every mode: the user data both ways per keyframe either end made
// (what is sent in one mode can be charged to the next: a backlog made out of range crosses when the
// link returns).
struct RobotPairTraffic {
  uint64_t user_bytes = 0, keyframes_both_ends = 0;

  std::optional<double> bytes_per_keyframe() const;
  nlohmann::json to_json() const;
};

// The radio's traffic (netns runs only): every robot, mode and link, the robot-to-robot links over the
// whole run, and the distributed traffic per keyframe on the worst link (robot to robot or robot to
// central: a DISTRIBUTED robot sends the central no keyframes, only the little a link that comes back
// carries before the robot rejoins).
struct TrafficSummary {
  std::vector<LinkModeTraffic> links;                             // by robot, mode, peer
  std::map<std::string, RobotPairTraffic> robot_links_whole_run;  // "robotA-robotB", A < B
  double max_robot_link_bytes_per_keyframe_whole_run = 0;
  double max_distributed_bytes_per_keyframe_per_link = 0;
  double max_distributed_sent_bytes_per_own_keyframe_per_link = 0;
  double max_distributed_bytes_per_keyframe_both_ends_per_link = 0;

  // report.json's "traffic".
  nlohmann::json to_json() const;
  // A robot's traffic per mode and peer (its entry's "traffic"); null when it counted nothing.
  nlohmann::json robot_json(uint32_t robot) const;
};

TrafficSummary summarise_traffic(const RunInfo& info);

// Per-topic payload of every service, from its --stats-out file: node -> service -> domain -> topic ->
// counters.
nlohmann::json topic_traffic(const std::filesystem::path& run, const std::vector<uint32_t>& robots);

}  // namespace cdc::launch
