// A swarm file: what cdc-launch starts (dataset, robots, network mode, domains, service
// configurations) and which variant of the system it runs.
#pragma once

#include "radio_faults.hpp"

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace cdc::launch {

enum class NetworkMode { kAuto, kNetns, kLoopback };

// The system variants of the paper's comparison (Table IV).
enum class Variant {
  kSingle,       // (a) every robot alone: odometry and its own loop closures, no radio at all
  kDistributed,  // (b) no central node: peers only, within their range
  kSwitching,    // (c)/(d) central while in range, peers otherwise
};

struct SwarmConfig {
  std::string path;  // the swarm file itself
  std::string name = "swarm";
  std::string scenario;  // cdc-sim scenario; the dataset is generated from it when missing
  std::string dataset;   // dataset folder (relative paths: to the project root)
  size_t max_scans = 0;  // per robot; 0: the whole dataset
  NetworkMode network = NetworkMode::kAuto;
  uint32_t slam_domain = 1;          // every SLAM topic (crosses the emulated radio)
  uint32_t sim_domain = 2;           // sensors, lock-step progress and the radio state (never cut)
  uint32_t local_domain_base = 100;  // robot K's own domain is this + K: its services talk there
                                     // (keyframes, corrections, its own descriptors and loops), never on the radio
  bool lockstep = true;
  double rate = 1.0;  // without lock-step: sim seconds per wall second
  bool lidar_only = false;
  Variant variant = Variant::kSwitching;
  bool frontend_correction = true;  // (d) with, (c) without
  double settle_s = 5.0;            // after the last sweep: time for the back-ends before shutdown
  double rendezvous_s = 0;          // > 0: after the last sweep every robot comes back in range (the end of the
                                    // mission); the run ends once all are CENTRALIZED, the central holding
                                    // all their keyframes, for settle_s; at most rendezvous_s + settle_s later
  std::string frontend_config = "services/frontend/config/frontend.yaml";
  std::string descriptor_config = "services/descriptor/config/descriptor.yaml";
  std::string loop_closure_config = "services/loop_closure/config/loop_closure.yaml";
  std::string peer_config = "services/peer_optimiser/config/peer_optimiser.yaml";
  std::string central_config = "services/central_optimiser/config/central_optimiser.yaml";
  std::string map_config = "services/map/config/map.yaml";
  bool map = true;
  bool range_periods = true;             // false: every pair stays in range; only radio_faults cut links
  std::vector<RadioFault> radio_faults;  // netns only: loss, one-way cuts, flapping, partitions
};

// Reads a swarm file; relative paths inside it are resolved against `root` (the project root).
// Throws config::ConfigError listing every problem.
SwarmConfig load_swarm(const std::string& path, const std::string& root);

const char* to_string(NetworkMode m);
std::optional<NetworkMode> parse_network_mode(std::string_view name);  // "auto", "netns", "loopback"
const char* to_string(Variant v);

}  // namespace cdc::launch
