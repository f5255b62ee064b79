// --mode-out FILE: every mode transition as a CSV line, written as it happens, and FILE.now, the
// robot's back-end state for a launcher, replaced atomically. No DDS here.
#pragma once

#include "cdc/peer_optimiser/rtdos.hpp"

#include <cstddef>
#include <cstdint>
#include <fstream>
#include <string>

namespace cdc::peer {

// What FILE.now says.
struct BackendState {
  Mode mode = Mode::kDistributed;
  size_t keyframes = 0;  // own keyframes taken in
  uint32_t transitions = 0;
  bool central_alive = false;
  int64_t acknowledged = -1;  // the central's highest contiguous keyframe id (-1: none)
};

class ModeFiles {
 public:
  // An empty path writes nothing. Throws std::runtime_error naming the file when it cannot be written.
  explicit ModeFiles(std::string path);

  // "wall_ns,sim_ns,robot,from,to,reason,distance_m,keyframes" (distance empty when unknown).
  void transition(const Transition& t, int64_t wall_ns, int64_t sim_ns, uint32_t robot, size_t keyframes);

  // FILE.now: "<mode> <keyframes> <transitions> <central alive 0|1> <keyframes acknowledged>", the
  // last the count of keyframes the central holds without a gap (its highest contiguous id + 1). A
  // launcher charges traffic to the mode it reads here (so the node writes it at once on a switch,
  // before the re-sends that follow one) and ends a rendezvous once the central holds every keyframe.
  void now(const BackendState& s) const;

 private:
  std::string path_;
  std::ofstream timeline_;
};

}  // namespace cdc::peer
