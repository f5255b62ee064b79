// Initial estimates that do not need good odometry.
#pragma once

#include "cdc/graph/pose_graph.hpp"

namespace cdc::graph {

// Chordal initialisation (Carlone et al., ICRA 2015): rotations from the linear relaxation of
// sum kappa ||R_j - R_i R_ij||_F^2 projected onto SO(3), then translations from the linear
// least squares with those rotations. The anchor (first key, or the key of the first prior)
// keeps its current pose. Every pose reachable through factors gets a value; returns false
// when the graph is not connected to the anchor.
bool chordal_initialise(PoseGraph& graph);

// Chains odometry (and, breadth-first, every other factor) from the anchor.
bool initialise_from_odometry(PoseGraph& graph);

}  // namespace cdc::graph
