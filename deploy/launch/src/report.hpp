// The results of a launched run: trajectories in TUM and KITTI formats, ATE/RPE per robot against
// the dataset's ground truth, the mode timeline, traffic per link and per mode, report.md and
// report.json, and plots (trajectories with the mode switches marked; mode over time).
#pragma once

#include "network.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace cdc::launch {

struct LinkEvent {
  double wall_s = 0, sim_s = 0;
  uint32_t a = 0, b = 0;
  bool up = true;
};

// A change of the drop probability of SLAM datagrams from src to dst (radio faults).
struct FaultEvent {
  double wall_s = 0, sim_s = 0;
  uint32_t src = 0, dst = 0;
  double drop = 0;
};

// Bytes and keyframes attributed to the mode the robot was in when they were counted.
struct ModeTraffic {
  std::map<std::string, std::map<uint32_t, LinkBytes>> bytes;  // mode -> peer node -> bytes
  std::map<std::string, uint64_t> keyframes;                   // mode -> keyframes made in it
  // mode -> robot peer -> keyframes that peer made while this robot was in the mode (the other end of
  // a robot-to-robot link makes keyframes too, and its descriptors and clouds cross the same link)
  std::map<std::string, std::map<uint32_t, uint64_t>> peer_keyframes;
};

struct RunInfo {
  std::string name, variant, network, dataset, run_dir, swarm_file;
  std::vector<uint32_t> robots;
  bool central = true;
  uint32_t slam_domain = 0, sim_domain = 0;  // how the per-topic table names the domains
  double wall_s = 0, sim_end_s = 0;
  bool interrupted = false;
  bool traffic_measured = false;  // per-link counters exist only in netns mode
  std::vector<LinkEvent> links;
  std::vector<FaultEvent> faults;           // radio faults applied (netns)
  uint64_t fault_dropped_datagrams = 0;     // SLAM datagrams the faults dropped
  std::map<uint32_t, ModeTraffic> traffic;  // per robot
  std::vector<std::string> notes;           // shown in the report (e.g. limits of the network mode)
  std::optional<double> rendezvous_s;       // how long the final rendezvous waited for the rejoins
  std::vector<uint32_t> not_rejoined;       // robots not CENTRALIZED, or not all keyframes with the central, at its end
  std::optional<double> caught_up_s;        // when every loop-closure service had caught up (after the last sweep)
  std::vector<uint32_t> loop_closure_busy;  // robots whose loop closure had not caught up at its end
};

// "central" or "robotN": how reports and traffic.csv name a node.
std::string node_name(uint32_t node);

// A number with a fixed count of decimals (tables of the reports).
std::string fixed(double v, int decimals);

// " 0 2": each id after a space (robots named in messages and reports).
std::string id_list(const std::vector<uint32_t>& ids);

// How far trajectory b lies from trajectory a, both in the same frame (two runs of one robot):
// RMS and largest distance between positions at matching stamps (within 5 ms); nullopt when a file
// is missing or no stamps match.
struct PositionDifference {
  double rms_m = 0, max_m = 0;
  size_t matched = 0;
};
std::optional<PositionDifference> position_difference(const std::string& tum_a, const std::string& tum_b);

// Writes every result file into info.run_dir and returns report.json's content.
nlohmann::json write_report(const RunInfo& info);

// cdc-experiment: several runs of one variant (rows as it reads them from each run's report.json:
// wall_s and robots -> figures) merged into one row: per robot the median of each figure over the
// runs that have it, the smallest and largest real-time ATE and every run's ATE; one row stays as is.
nlohmann::json merge_runs(const std::vector<nlohmann::json>& rows);

}  // namespace cdc::launch
