#include "cdc/graph/pose_graph.hpp"

#include <algorithm>

namespace cdc::graph {

void PoseGraph::add_prior(Key key, const Eigen::Isometry3d& T_world_key, const Matrix6d& information) {
  Factor f;
  f.kind = FactorKind::kPrior;
  f.a = f.b = key;
  f.measurement = T_world_key;
  f.information = information;
  factors.push_back(f);
}

void PoseGraph::add_between(Key a, Key b, const Eigen::Isometry3d& T_a_b, const Matrix6d& information) {
  Factor f;
  const bool odometry = robot_of(a) == robot_of(b) && index_of(b) == index_of(a) + 1;
  f.kind = odometry ? FactorKind::kOdometry : FactorKind::kLoop;
  f.a = a;
  f.b = b;
  f.measurement = T_a_b;
  f.information = information;
  f.robust = !odometry;
  factors.push_back(f);
}

size_t PoseGraph::count(FactorKind kind) const {
  return static_cast<size_t>(std::count_if(factors.begin(), factors.end(), [&](const Factor& f) { return f.kind == kind; }));
}

std::map<Key, int> loop_counts(const PoseGraph& graph) {
  std::map<Key, int> counts;
  for (const Factor& f : graph.factors) {
    if (f.kind == FactorKind::kLoop) {
      ++counts[f.a];
      ++counts[f.b];
    }
  }
  return counts;
}

void share_loop_information(PoseGraph& graph, const std::map<Key, int>& counts) {
  auto count_of = [&](Key k) {
    const auto it = counts.find(k);
    return it == counts.end() ? 1 : std::max(it->second, 1);
  };
  for (Factor& f : graph.factors) {
    if (f.kind == FactorKind::kLoop) {
      f.information /= static_cast<double>(std::max(count_of(f.a), count_of(f.b)));
    }
  }
}

}  // namespace cdc::graph
