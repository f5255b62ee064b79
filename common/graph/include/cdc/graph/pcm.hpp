// Outlier rejection for inter-robot loop closures. PCM (pairwise consistency maximisation,
// Mangelson et al. 2018) is one implementation: for every pair of robots, two loop closures are
// consistent when the cycle they close with the two robots' odometry is within a Mahalanobis
// threshold; the largest set of mutually consistent loops (a maximum clique) is kept.
#pragma once

#include "cdc/graph/pose_graph.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace cdc::graph {

struct OutlierDecision {
  std::vector<size_t> accepted;  // indices into PoseGraph::factors
  std::vector<size_t> rejected;
};

class OutlierRejection {
 public:
  virtual ~OutlierRejection() = default;
  // Decides on every inter-robot loop factor of the graph, using its odometry factors.
  virtual OutlierDecision decide(const PoseGraph& graph) const = 0;
};

struct PcmOptions {
  double chi2_threshold = 16.81;   // 6 DoF at 99 %
  size_t exact_clique_limit = 64;  // loops per robot pair solved exactly; more use a greedy heuristic
};

class Pcm : public OutlierRejection {
 public:
  explicit Pcm(const PcmOptions& options = {}) : options_(options) {}
  OutlierDecision decide(const PoseGraph& graph) const override;

  // Mahalanobis distance^2 of the cycle closed by two loops between the same two robots (exposed
  // for tests and reports).
  static double cycle_distance(const PoseGraph& graph, const Factor& k, const Factor& l);

  // Mahalanobis distance^2 between an intra-robot loop and the robot's odometry between its two
  // keyframes (the cycle a single loop closes), with the odometry covariance propagated.
  static double odometry_distance(const PoseGraph& graph, const Factor& loop);

 private:
  PcmOptions options_;
};

// Maximum clique of an undirected graph given as an adjacency matrix over 0..n-1: exact (branch and
// bound from a greedy clique) up to `exact_limit` vertices and `max_steps` expansions, a greedy
// heuristic above. Past either limit the result is a clique, perhaps not the largest; `exact`, when
// given, says whether it is known to be the largest.
std::vector<size_t> maximum_clique(const std::vector<std::vector<bool>>& adjacency, size_t exact_limit = 64,
                                   size_t max_steps = 20000, bool* exact = nullptr);

}  // namespace cdc::graph
