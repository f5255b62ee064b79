// DDS glue of the loop-closure service: the robot's keyframes and every robot's descriptors in;
// cloud requests and replies between owners; loop closures out, with byte counters per topic and
// per peer.
#pragma once

#include "loop_config.hpp"

#include <string>

namespace cdc::loops {

int run_loop_closure(const LoopNodeOptions& options);

}  // namespace cdc::loops
