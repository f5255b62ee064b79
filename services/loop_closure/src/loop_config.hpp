// The loop-closure service's configuration (services/loop_closure/config/loop_closure.yaml): the
// core's parameters and the node's, read and checked in one place for the service and cdc-loops.
#pragma once

#include "cdc/loop_closure/descriptor_sequencer.hpp"
#include "cdc/loop_closure/loop_core.hpp"
#include "cdc/loop_closure/peer_reach.hpp"

#include <string>

namespace cdc::loops {

struct LoopNodeOptions {
  uint32_t robots = 3;  // the robot's id, domains and statistics file are the shared options' (runtime)
  std::string log_level = "info";
  // Rewritten (atomically) as the work left changes: "<descriptors waiting to be searched> <cloud
  // requests pending> <cloud requests parked> <loops published>", for a launcher that ends a mission
  // once every loop-closure service has caught up. Empty: not written.
  std::string backlog_out;
  std::string state_file;  // where the loop numbering is kept across restarts (LoopNumbering); empty: nowhere
  LoopParams core;
  PeerReachParams reach;  // a peer unheard of reach.silence is out of range: no cloud requests to it
  int tick_ms = 100;
  float reply_resolution_m = 0.02f;  // quantisation of the clouds sent in cloud replies
  SequencerParams sequencer;         // asking for missed descriptors
};

// Reads a configuration file; throws config::ConfigError naming every bad or unknown key.
LoopNodeOptions load_loop_options(const std::string& path);

}  // namespace cdc::loops
