#include "cdc/graph/distributed.hpp"

#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "residuals.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <set>

namespace cdc::graph {
namespace {

double objective(const PoseGraph& g, Objective o) {
  return o == Objective::kSeSync ? sesync_objective(g) : full_information_cost(g);
}

std::set<uint32_t> robots_of(const PoseGraph& g) {
  std::set<uint32_t> r;
  for (const auto& [k, _] : g.poses) {
    r.insert(robot_of(k));
  }
  for (const Factor& f : g.factors) {
    r.insert(robot_of(f.a));
    r.insert(robot_of(f.b));
  }
  return r;
}

// Records that `from` sent pose `key` to every other robot it shares an inter-robot factor with.
struct Exchange {
  const PoseGraph& g;
  DistributedResult* acc;
  std::map<Key, std::set<uint32_t>> audience;  // separator key -> robots that need it

  Exchange(const PoseGraph& graph, DistributedResult* accounting) : g(graph), acc(accounting) {
    for (const Factor& f : g.factors) {
      if (f.kind != FactorKind::kPrior && f.inter_robot()) {
        audience[f.a].insert(robot_of(f.b));
        audience[f.b].insert(robot_of(f.a));
      }
    }
  }
  void send_separators(uint32_t robot) {
    if (acc == nullptr) {
      return;
    }
    for (const auto& [k, to] : audience) {
      if (robot_of(k) == robot) {
        acc->poses_sent[robot] += to.size();
        acc->bytes_sent[robot] += to.size() * kSeparatorPoseBytes;
      }
    }
  }
};

// Moves every pose of robot r by the rigid correction C (T <- C * T).
void move_robot(PoseGraph& graph, uint32_t r, const Eigen::Isometry3d& C) {
  for (auto& [k, T] : graph.poses) {
    if (robot_of(k) == r) {
      T = C * T;
    }
  }
}

// Solves for one rigid correction C of robot r's poses against the given inter-robot factors
// (the other robots fixed) and applies it.
void rigid_correction(PoseGraph& graph, uint32_t r, const std::vector<const Factor*>& factors,
                      const SolverOptions& options) {
  double ct[3] = {0, 0, 0};
  double cq[4] = {0, 0, 0, 1};
  ceres::Problem problem;
  int count = 0;
  for (const Factor* f : factors) {
    if (f->kind == FactorKind::kPrior || !f->inter_robot()) {
      continue;
    }
    const bool mine_is_a = robot_of(f->a) == r;
    const Key mine = mine_is_a ? f->a : f->b;
    const Key other = mine_is_a ? f->b : f->a;
    const Matrix6d L = f->information.llt().matrixL().transpose();
    problem.AddResidualBlock(detail::RigidCorrectionResidual::create(graph.poses.at(mine), graph.poses.at(other),
                                                                     f->measurement, L, mine_is_a),
                             nullptr, ct, cq);
    ++count;
  }
  if (count == 0) {
    return;
  }
  problem.SetManifold(cq, new ceres::EigenQuaternionManifold);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = options.max_iterations;
  so.initial_trust_region_radius = options.initial_trust_region_radius;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  Eigen::Isometry3d C = Eigen::Isometry3d::Identity();
  C.linear() = Eigen::Quaterniond(cq[3], cq[0], cq[1], cq[2]).normalized().toRotationMatrix();
  C.translation() = Eigen::Vector3d(ct[0], ct[1], ct[2]);
  move_robot(graph, r, C);
}

// Chordal initialisation of robot r's own subgraph (intra-robot factors only), in a frame anchored
// at its first pose's current value (identity when it has none).
void initialise_robot(PoseGraph& graph, uint32_t r) {
  PoseGraph local;
  local.dimension = graph.dimension;
  for (const Factor& f : graph.factors) {
    if (robot_of(f.a) == r && robot_of(f.b) == r) {
      local.factors.push_back(f);
    }
  }
  if (local.factors.empty()) {
    return;
  }
  Key first = ~Key{0};
  for (const Factor& f : local.factors) {
    first = std::min({first, f.a, f.b});
  }
  auto it = graph.poses.find(first);
  local.poses[first] = it != graph.poses.end() ? it->second : Eigen::Isometry3d::Identity();
  chordal_initialise(local);
  for (const auto& [k, T] : local.poses) {
    graph.poses[k] = T;
  }
}

// Whether f is an inter-robot factor between robot r and a placed robot.
bool links_to_placed(const Factor& f, uint32_t r, const std::set<uint32_t>& placed) {
  return f.kind != FactorKind::kPrior && f.inter_robot() &&
         ((robot_of(f.a) == r && placed.count(robot_of(f.b)) != 0) ||
          (robot_of(f.b) == r && placed.count(robot_of(f.a)) != 0));
}

// Places robot r in the world through the most informative inter-robot factor to a placed robot,
// then refines the placement with all of them. False when r shares none with a placed robot.
bool place_robot(PoseGraph& graph, uint32_t r, const std::set<uint32_t>& placed) {
  const Factor* best = nullptr;
  std::vector<const Factor*> to_placed;
  for (const Factor& f : graph.factors) {
    if (!links_to_placed(f, r, placed)) {
      continue;
    }
    to_placed.push_back(&f);
    if (best == nullptr || f.information.trace() > best->information.trace()) {
      best = &f;
    }
  }
  if (best == nullptr) {
    return false;
  }
  // T_world_new = T_world_other * T_other_mine * inv(T_local_mine): a rigid move of robot r.
  const bool mine_is_b = robot_of(best->b) == r;
  const Key mine = mine_is_b ? best->b : best->a;
  const Key other = mine_is_b ? best->a : best->b;
  const Eigen::Isometry3d T_other_mine = mine_is_b ? best->measurement : best->measurement.inverse();
  move_robot(graph, r, graph.poses.at(other) * T_other_mine * graph.poses.at(mine).inverse());
  rigid_correction(graph, r, to_placed, SolverOptions{});
  return true;
}

// Per robot: the factors touching its poses.
std::map<uint32_t, std::vector<const Factor*>> factors_by_robot(const PoseGraph& graph) {
  std::map<uint32_t, std::vector<const Factor*>> factors;
  for (const Factor& f : graph.factors) {
    factors[robot_of(f.a)].push_back(&f);
    if (robot_of(f.b) != robot_of(f.a)) {
      factors[robot_of(f.b)].push_back(&f);
    }
  }
  return factors;
}

// Robot r's local problem: its factors, the poses they name (the neighbours' separator poses as
// last received, held fixed) and the gauge when it is r's.
struct LocalProblem {
  PoseGraph graph;
  std::set<Key> fixed;
};

LocalProblem local_problem(const PoseGraph& graph, uint32_t r, const std::vector<const Factor*>& factors, Key gauge) {
  LocalProblem local;
  local.graph.dimension = graph.dimension;
  for (const Factor* f : factors) {
    local.graph.factors.push_back(*f);
    for (Key k : {f->a, f->b}) {
      local.graph.poses[k] = graph.poses.at(k);
      if (robot_of(k) != r) {
        local.fixed.insert(k);  // a neighbour's separator pose, as last received
      }
    }
  }
  if (local.graph.factors.empty()) {
    return local;
  }
  if (robot_of(gauge) == r) {
    local.fixed.insert(gauge);
  }
  if (local.fixed.empty()) {
    local.fixed.insert(local.graph.poses.begin()->first);  // an isolated robot anchors itself
  }
  return local;
}

// Moves robot r's poses in `graph` towards their local solution by the over-relaxation factor g
// (translation linearly, rotation along the geodesic). Returns the largest move [m, rad].
double relax_towards(PoseGraph& graph, uint32_t r, const PoseGraph& solution, double g) {
  double max_change = 0.0;
  for (const auto& [k, T] : solution.poses) {
    if (robot_of(k) != r) {
      continue;
    }
    const Eigen::Isometry3d old = graph.poses.at(k);
    Eigen::Isometry3d next = Eigen::Isometry3d::Identity();
    next.translation() = old.translation() + g * (T.translation() - old.translation());
    const Eigen::AngleAxisd step(old.rotation().transpose() * T.rotation());
    next.linear() = old.rotation() * Eigen::AngleAxisd(g * step.angle(), step.axis()).toRotationMatrix();
    const double dt = (next.translation() - old.translation()).norm();
    max_change = std::max({max_change, dt, g * step.angle()});
    graph.poses[k] = next;
  }
  return max_change;
}

}  // namespace

bool initialise_distributed(PoseGraph& graph, DistributedResult* accounting) {
  const std::set<uint32_t> robots = robots_of(graph);
  if (robots.empty()) {
    return true;
  }
  for (uint32_t r : robots) {
    initialise_robot(graph, r);
  }
  // Place robots in the world, breadth-first from the anchor robot.
  Exchange exchange(graph, accounting);
  std::set<uint32_t> placed{*robots.begin()};
  exchange.send_separators(*robots.begin());
  bool progress = true;
  while (placed.size() < robots.size() && progress) {
    progress = false;
    for (uint32_t r : robots) {
      if (placed.count(r) != 0 || !place_robot(graph, r, placed)) {
        continue;
      }
      placed.insert(r);
      exchange.send_separators(r);
      progress = true;
    }
  }
  return placed.size() == robots.size();
}

DistributedResult solve_distributed(PoseGraph& graph, const DistributedOptions& options) {
  DistributedResult result;
  const std::set<uint32_t> robots = robots_of(graph);
  const Key gauge = graph.poses.empty() ? 0 : graph.poses.begin()->first;
  result.objective_per_round.push_back(objective(graph, options.local.objective));
  Exchange exchange(graph, &result);
  std::map<uint32_t, std::vector<const Factor*>> factors = factors_by_robot(graph);

  for (int round = 1; round <= options.max_rounds; ++round) {
    double max_change = 0.0;
    for (uint32_t r : robots) {
      LocalProblem local = local_problem(graph, r, factors[r], gauge);
      if (local.graph.factors.empty()) {
        continue;
      }
      solve(local.graph, options.local, local.fixed);
      max_change = std::max(max_change, relax_towards(graph, r, local.graph, options.over_relaxation));
      exchange.send_separators(r);
    }
    result.rounds = round;
    result.objective_per_round.push_back(objective(graph, options.local.objective));
    if (max_change < options.pose_change_tolerance) {
      result.converged = true;
      break;
    }
  }
  return result;
}

}  // namespace cdc::graph
