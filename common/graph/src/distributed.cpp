#include "cdc/graph/distributed.hpp"

#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "relax.hpp"
#include "residuals.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <chrono>
#include <set>
#include <utility>

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
    double change = 0.0;
    graph.poses[k] = detail::relax_pose(graph.poses.at(k), T, g, &change);
    max_change = std::max(max_change, change);
  }
  return max_change;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The gauge of a graph without priors: its smallest key.
std::optional<Key> gauge_of(const PoseGraph& g) {
  std::optional<Key> gauge;
  for (const Factor& f : g.factors) {
    if (f.kind == FactorKind::kPrior) {
      return std::nullopt;
    }
    gauge = std::min({gauge.value_or(f.a), f.a, f.b});
  }
  if (!g.poses.empty()) {
    gauge = std::min(gauge.value_or(g.poses.begin()->first), g.poses.begin()->first);
  }
  return gauge;
}

// Simulated radio of one stage: the latest estimate of every separator sent so far, and the bytes.
template <class Value>
struct Postbox {
  std::map<Key, Value> latest;
  uint64_t bytes_each = 0;
  uint64_t copies_each = 0;  // > 0: every estimate goes to this many robots, else to its audience

  bool parallel = false;  // robots read what was sent before the round (block Jacobi)
  std::map<Key, Value> delivered;

  void begin_round() {
    if (parallel) {
      delivered = latest;
    }
  }
  std::map<Key, Value> inbox(const DistributedRobot& robot) const {
    std::map<Key, Value> in;
    const std::map<Key, Value>& from = parallel ? delivered : latest;
    for (Key k : robot.needed()) {
      if (auto it = from.find(k); it != from.end()) {
        in.emplace(k, it->second);
      }
    }
    return in;
  }
  // Posts the robot's separator estimates, one copy per robot that needs each; returns the bytes.
  uint64_t post(const DistributedRobot& robot, const std::map<Key, Value>& values, DistributedResult& acc) {
    uint64_t bytes = 0;
    for (const auto& [k, v] : values) {
      latest[k] = v;
      const auto audience = robot.audience().find(k);
      const uint64_t copies = copies_each > 0                      ? copies_each
                              : audience != robot.audience().end() ? audience->second.size()
                                                                   : 0;
      acc.poses_sent[robot.robot()] += copies;
      bytes += copies * bytes_each;
    }
    acc.bytes_sent[robot.robot()] += bytes;
    return bytes;
  }
};

// Runs rounds of one stage until the largest change falls below `tolerance` or `max_rounds` pass.
// step(robot, inbox, round) updates a robot and returns its largest change; separators(robot) is
// what it sends. Returns the rounds run and whether the tolerance was met.
template <class Value, class Step, class Separators>
std::pair<int, bool> run_stage(std::vector<DistributedRobot>& team, Postbox<Value>& box, int max_rounds,
                               double tolerance, DistributedResult& result, Step step, Separators separators) {
  for (int round = 1; round <= max_rounds; ++round) {
    box.begin_round();
    double change = 0.0;
    uint64_t bytes = 0;
    for (DistributedRobot& robot : team) {
      const auto t0 = std::chrono::steady_clock::now();
      change = std::max(change, step(robot, box.inbox(robot), round));
      result.compute_s[robot.robot()] += seconds_since(t0);
      bytes += box.post(robot, separators(robot), result);
    }
    result.bytes_per_round.push_back(bytes);
    ++result.rounds;
    if (change < tolerance) {
      return {round, true};
    }
  }
  return {max_rounds, false};
}

void write_poses(const std::vector<DistributedRobot>& team, PoseGraph& graph) {
  for (const DistributedRobot& robot : team) {
    for (const auto& [k, T] : robot.poses()) {
      graph.poses[k] = T;
    }
  }
}

// The factors of the coarse problem (inter-robot factors, priors, factors at the gauge or at a
// pose with a prior); each robot sends the ones it is the first end of, once, to every robot that
// does not hold them yet.
std::vector<Factor> coarse_factors(const PoseGraph& graph, size_t robots, DistributedResult& result, uint64_t& bytes) {
  std::set<Key> pinned;
  if (const std::optional<Key> gauge = gauge_of(graph)) {
    pinned.insert(*gauge);
  }
  for (const Factor& f : graph.factors) {
    if (f.kind == FactorKind::kPrior) {
      pinned.insert(f.a);
    }
  }
  std::vector<Factor> out;
  for (const Factor& f : graph.factors) {
    if (f.inter_robot() || pinned.count(f.a) != 0 || pinned.count(f.b) != 0) {
      out.push_back(f);
      const uint64_t b = (robots - (f.inter_robot() ? 2 : 1)) * kFactorBytes;
      result.bytes_sent[robot_of(f.a)] += b;
      bytes += b;
    }
  }
  return out;
}

// One round of stage 3: block solves in robot order, then (with the coarse step) the rigid
// corrections every robot computes from all separator poses. Returns the largest change.
double pose_round(std::vector<DistributedRobot>& team, Postbox<Eigen::Isometry3d>& box,
                  const std::vector<Factor>* coarse, const PoseGraph& graph, const DistributedOptions& options,
                  DistributedResult& result) {
  box.begin_round();
  const TwoStageOptions& o = options.two_stage;
  const double gamma = o.parallel ? std::min(o.pose_over_relaxation, 1.0) : o.pose_over_relaxation;
  double change = 0.0;
  uint64_t bytes = 0;
  for (DistributedRobot& robot : team) {
    const auto t0 = std::chrono::steady_clock::now();
    change = std::max(change, robot.pose_round(box.inbox(robot), options.local, gamma));
    result.compute_s[robot.robot()] += seconds_since(t0);
    bytes += box.post(robot, coarse != nullptr ? robot.coarse_separators() : robot.pose_separators(), result);
  }
  result.bytes_per_round.push_back(bytes);
  ++result.rounds;
  if (coarse == nullptr) {
    return change;
  }
  const std::optional<Key> gauge = gauge_of(graph);
  const auto t0 = std::chrono::steady_clock::now();
  const auto C = coarse_corrections(*coarse, box.latest, gauge, options.local, graph.dimension);
  const double coarse_s = seconds_since(t0);
  for (DistributedRobot& robot : team) {
    result.compute_s[robot.robot()] += coarse_s;  // every robot solves the same coarse problem
    change = std::max(change, robot.move(C));
  }
  for (auto& [k, T] : box.latest) {
    T = C.of(k) * T;  // what every robot does to the separator poses it holds
  }
  return change;
}

// Stage 3 from what every robot already holds after stages 1-2: its neighbours' last rotations and
// translations make their separator poses.
void refine_poses(PoseGraph& graph, std::vector<DistributedRobot>& team, const DistributedOptions& options,
                  DistributedResult& result) {
  const bool coarse = options.two_stage.coarse && team.size() > 1;
  Postbox<Eigen::Isometry3d> box{{}, kSeparatorPoseBytes, coarse ? team.size() - 1 : 0, options.two_stage.parallel, {}};
  for (const DistributedRobot& r : team) {
    for (const auto& [k, T] : r.pose_separators()) {
      box.latest[k] = T;
    }
  }
  write_poses(team, graph);
  result.objective_first_round = result.rounds;
  result.objective_per_round.push_back(objective(graph, options.local.objective));
  uint64_t factor_bytes = 0;
  const std::vector<Factor> factors =
      coarse ? coarse_factors(graph, team.size(), result, factor_bytes) : std::vector<Factor>{};
  for (int round = result.rounds; round < options.max_rounds; ++round) {
    const double change = pose_round(team, box, coarse ? &factors : nullptr, graph, options, result);
    result.bytes_per_round.back() += std::exchange(factor_bytes, 0);  // sent with the first round's separators
    write_poses(team, graph);
    result.objective_per_round.push_back(objective(graph, options.local.objective));
    if (change < options.pose_change_tolerance) {
      result.converged = true;
      break;
    }
  }
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

DistributedResult solve_distributed_two_stage(PoseGraph& graph, const DistributedOptions& options) {
  DistributedResult result;
  const TwoStageOptions& o = options.two_stage;
  std::vector<DistributedRobot> team;
  for (uint32_t r : robots_of(graph)) {
    team.emplace_back(graph, r, gauge_of(graph));
  }
  // The first round of a linear stage starts from values not yet consistent between robots: no
  // over-relaxation there.
  const auto omega = [&](int round) { return round == 1 || o.parallel ? 1.0 : o.linear_over_relaxation; };
  Postbox<Eigen::Matrix3d> rotations{{}, kSeparatorRotationBytes, 0, o.parallel, {}};
  result.rotation_rounds =
      run_stage(
          team, rotations, std::min(o.max_rotation_rounds, options.max_rounds), o.rotation_tolerance, result,
          [&](DistributedRobot& r, const SeparatorRotations& in, int round) {
            return r.rotation_round(in, omega(round));
          },
          [](const DistributedRobot& r) { return r.rotation_separators(); })
          .first;
  for (DistributedRobot& r : team) {
    r.end_rotations(rotations.inbox(r));
  }
  Postbox<Eigen::Vector3d> translations{{}, kSeparatorTranslationBytes, 0, o.parallel, {}};
  result.translation_rounds =
      run_stage(
          team, translations, std::min(o.max_translation_rounds, options.max_rounds - result.rounds),
          o.translation_tolerance, result,
          [&](DistributedRobot& r, const SeparatorTranslations& in, int round) {
            return r.translation_round(in, omega(round));
          },
          [](const DistributedRobot& r) { return r.translation_separators(); })
          .first;
  refine_poses(graph, team, options, result);
  return result;
}

}  // namespace cdc::graph
