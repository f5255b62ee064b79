// Distributed pose-graph optimisation over robots (block Gauss-Seidel, in the spirit of
// distributed Gauss-Seidel / DGS): robots take turns optimising their own poses with the
// neighbours' separator poses (the poses inter-robot factors touch) held constant, and exchange
// only those separator poses. Pure: the exchange is simulated, the bytes are counted.
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/graph/solver.hpp"

#include <cstdint>
#include <map>
#include <vector>

namespace cdc::graph {

struct DistributedOptions {
  int max_rounds = 30;
  // Stop when no robot moved a pose by more than this in a round [m, rad] (1 mm, 1 mrad).
  double pose_change_tolerance = 1e-3;
  // Successive over-relaxation: each pose moves gamma times its local update (translation
  // linearly, rotation along the geodesic). 1 is plain Gauss-Seidel; 1 < gamma < 2 speeds up the
  // slow, smooth error modes that Gauss-Seidel leaves behind.
  double over_relaxation = 1.7;
  SolverOptions local;  // the per-robot solve
};

struct DistributedResult {
  int rounds = 0;
  bool converged = false;
  std::vector<double> objective_per_round;  // after initialisation (index 0) and each round
  std::map<uint32_t, uint64_t> bytes_sent;  // separator poses sent, per robot [bytes]
  std::map<uint32_t, uint64_t> poses_sent;
};

// Bytes of one separator pose on the wire (cdc_msg_KeyframePoseF): keyframe id + position and quaternion in 7 floats.
inline constexpr uint64_t kSeparatorPoseBytes = 4 + 7 * 4;

// Each robot initialises its own subgraph (chordal), then is placed in the world by a rigid fit
// to all its inter-robot factors with already placed robots (robot of the smallest key anchors).
// Returns false when some robot cannot be reached through inter-robot factors.
bool initialise_distributed(PoseGraph& graph, DistributedResult* accounting = nullptr);

// Optimises graph.poses in place by rounds of block Gauss-Seidel over robots. The robot of the
// smallest key holds its first pose fixed (gauge). Objective values use options.local.objective.
DistributedResult solve_distributed(PoseGraph& graph, const DistributedOptions& options);

}  // namespace cdc::graph
