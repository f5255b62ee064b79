// DDS glue of the loop-closure service: the robot's keyframes and every robot's descriptors in;
// cloud requests and replies between owners; loop closures out, with byte counters per topic and
// per peer.
#pragma once

#include "cdc/loop_closure/descriptor_sequencer.hpp"
#include "cdc/loop_closure/loop_core.hpp"

#include <string>

namespace cdc::loops {

struct LoopNodeOptions {
  uint32_t robot = 0, robots = 3, domain = 0;
  int local_domain = -1;  // the robot's own domain (see cdc/dds/robot_domains.hpp); -1: none
  std::string dds_config, local_dds_config, stats_out, log_level = "info";
  LoopParams core;
  int peer_timeout_ms = 3000;   // a peer unheard of this long is out of range: no cloud requests to it
  int tick_ms = 100;
  float reply_resolution_m = 0.01f;  // quantisation of the clouds sent in cloud replies
  SequencerParams sequencer;         // asking for missed descriptors
};

LoopNodeOptions load_loop_options(const std::string& path);
int run_loop_closure(const LoopNodeOptions& options);

}  // namespace cdc::loops
