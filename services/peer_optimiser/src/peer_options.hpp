// The peer optimiser's configuration (services/peer_optimiser/config/peer_optimiser.yaml) and what
// the command line adds to it; no DDS here.
#pragma once

#include "cdc/peer_optimiser/peer_core.hpp"

#include <string>

namespace cdc::peer {

// The domains and the statistics file are the shared options' (runtime::ServiceOptions); core.robot is
// --robot's.
struct PeerNodeOptions {
  PeerConfig core;
  uint32_t central_id = 200;  // the central's node id in status messages
  int tick_ms = 50;
  int status_period_ms = 250;  // the launcher's status file (--mode-out FILE.now)
  // The robot's status on the radio (cdc/status/robot: its pose for peers' peer_range_m); each
  // sample costs every peer in reach ~0.2 KB with its headers and acknowledgement.
  int radio_status_period_ms = 1000;
  int mode_period_ms = 1000;  // the mode is re-published this often besides every transition
  // Grid of the keyframe clouds packed for the central's map (cdc/map/keyframe_cloud) [m]: finer
  // than the map's voxel (cdc-map cloud_voxel_m); rounding moves a point by at most half a step per axis.
  float map_cloud_resolution_m = 0.02f;
  std::string mode_out;        // CSV of every mode transition, written as it happens
  std::string trajectory_out;  // TUM: own keyframes in W as last corrected, written at shutdown
  std::string graph_out;       // g2o: PeerCore::graph(), written at shutdown
  std::string log_level = "info";
};

// Loads a YAML configuration over the defaults (empty path: the defaults; the robot id comes from
// the command line). Every invalid key is named in the config::ConfigError thrown.
PeerNodeOptions load_options(const std::string& path);

}  // namespace cdc::peer
