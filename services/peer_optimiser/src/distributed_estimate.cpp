#include "cdc/peer_optimiser/distributed_estimate.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/graph/distributed_robot.hpp"
#include "cdc/graph/solver.hpp"

#include <algorithm>

namespace cdc::peer {
namespace {

constexpr double kAnchorInformation = 1e6;
constexpr int kGncRounds = 30;  // GNC rounds per block solve at most (mu doubles each round)
// A key index no keyframe has (ids are 32-bit): as the coarse step's gauge, its robot holds still
// as a whole (graph::coarse_corrections).
constexpr uint64_t kNoKeyframe = (uint64_t{1} << 56) - 1;

// The robots the factors link to `robot`, directly or through others (robot included).
std::set<uint32_t> component_of(uint32_t robot, const std::vector<graph::Factor>& factors) {
  std::set<uint32_t> reached{robot};
  for (bool grew = true; grew;) {
    grew = false;
    for (const graph::Factor& f : factors) {
      const uint32_t a = graph::robot_of(f.a), b = graph::robot_of(f.b);
      if ((reached.count(a) != 0) != (reached.count(b) != 0)) {
        reached.insert(reached.count(a) != 0 ? b : a);
        grew = true;
      }
    }
  }
  return reached;
}

}  // namespace

void DistributedEstimate::extend(const OwnKeyframe& kf) {
  auto prev = estimate_.find(kf.id - 1u);
  if (kf.id > 0 && prev != estimate_.end()) {
    estimate_[kf.id] = prev->second * kf.T_prev;
  }
}

void DistributedEstimate::seed(const LocalGraph& known, const KeyframePoses& central,
                               const std::optional<Eigen::Isometry3d>& T_world_robot) {
  const std::map<uint32_t, Eigen::Isometry3d> central_poses(central.begin(), central.end());
  for (const auto& [id, kf] : known.keyframes()) {
    if (estimate_.count(id) != 0) {
      continue;
    }
    if (auto c = central_poses.find(id); c != central_poses.end()) {
      estimate_[id] = c->second;
    } else if (auto prev = estimate_.find(id - 1); id > 0 && prev != estimate_.end()) {
      estimate_[id] = prev->second * kf.T_prev;
    } else {
      estimate_[id] = T_world_robot.value_or(Eigen::Isometry3d::Identity()) * kf.T_odom;
    }
  }
}

std::optional<Eigen::Isometry3d> DistributedEstimate::round(const LocalGraph& known, const KeyframePoses& central,
                                                            const std::optional<Eigen::Isometry3d>& T_world_robot) {
  if (known.keyframes().empty()) {
    return std::nullopt;
  }
  seed(known, central, T_world_robot);
  if (central.empty() && !placed_by_peers_) {
    placed_by_peers_ = place_through_peers(known);
  }
  Separators separators = known.separators();
  const Coarse coarse = config_.coarse_step && central.empty() ? coarse_step(known, separators) : Coarse{};
  Problem p = problem(known, separators);
  anchor(p, known, central, coarse);
  if (p.graph.factors.empty()) {
    return std::nullopt;
  }
  solve(p);
  relax_towards(p.graph);
  if (coarse.gauge == known.robot() && !p.fixed.empty()) {
    hold_gauge(known);
  }
  ++rounds_;
  return known.world_transform_of(KeyframePoses(estimate_.begin(), estimate_.end()));
}

// Without a central estimate, a robot that is not the lowest of its group starts in its own
// odometry frame: it is placed rigidly through its most informative loop to a lower robot's
// separator pose before solving (robust losses would otherwise discount exactly those loops).
bool DistributedEstimate::place_through_peers(const LocalGraph& known) {
  const uint32_t me = known.robot();
  const auto& separators = known.separators();
  const LoopRecord* best = nullptr;
  for (const LoopRecord& l : known.loops()) {
    const bool a_mine = l.robot_a == me, b_mine = l.robot_b == me;
    if (l.withdrawn || a_mine == b_mine) {
      continue;
    }
    const uint32_t other = a_mine ? l.robot_b : l.robot_a;
    const uint32_t other_kf = a_mine ? l.keyframe_b : l.keyframe_a;
    const uint32_t my_kf = a_mine ? l.keyframe_a : l.keyframe_b;
    if (other < me && separators.count(graph::make_key(other, other_kf)) != 0 && estimate_.count(my_kf) != 0 &&
        (best == nullptr || l.information.trace() > best->information.trace())) {
      best = &l;
    }
  }
  if (best == nullptr) {
    return false;
  }
  const bool a_mine = best->robot_a == me;
  const Eigen::Isometry3d T_other = separators.at(
      graph::make_key(a_mine ? best->robot_b : best->robot_a, a_mine ? best->keyframe_b : best->keyframe_a));
  const Eigen::Isometry3d T_other_mine = a_mine ? best->T_a_b.inverse() : best->T_a_b;
  const Eigen::Isometry3d T_mine = estimate_.at(a_mine ? best->keyframe_a : best->keyframe_b);
  const Eigen::Isometry3d correction = T_other * T_other_mine * T_mine.inverse();
  for (auto& [id, T] : estimate_) {
    T = correction * T;
  }
  return true;
}

// The coarse step (graph::coarse_corrections) over the inter-robot loops of this robot's group whose
// two poses are known: one rigid move per robot, the group's lowest robot held still. Every robot of
// the group solves it from the same loops (its own and those its peers relay) and the same poses
// (its own as it sent them, its peers' as they sent them), so they all find the same moves; each
// applies its own to its keyframes and its peers' to the separator poses it holds.
DistributedEstimate::Coarse DistributedEstimate::coarse_step(const LocalGraph& known, Separators& separators) {
  const uint32_t me = known.robot();
  graph::PoseGraph g;
  for (const auto& [id, T] : estimate_) g.poses[graph::make_key(me, id)] = T;
  for (const auto& [k, T] : separators) g.poses[k] = T;
  for (const LoopRecord* l : known.inter_robot_loops()) {
    const Key a = graph::make_key(l->robot_a, l->keyframe_a), b = graph::make_key(l->robot_b, l->keyframe_b);
    if (g.poses.count(a) != 0 && g.poses.count(b) != 0) g.add_between(a, b, l->T_a_b, l->information);
  }
  const std::set<uint32_t> group = component_of(me, g.factors);
  const bool complete =
      std::all_of(group.begin(), group.end(), [&](uint32_t r) { return known.shares_coarse_step_with(r); });
  if (group.size() < 2 || !complete) {
    return {};  // another robot would solve another coarse problem: this one's moves would be biased
  }
  if (config_.share_loop_information) {
    graph::share_loop_information(g);
  }
  std::erase_if(g.factors, [&](const graph::Factor& f) { return group.count(graph::robot_of(f.a)) == 0; });
  const uint32_t gauge = *group.begin();
  graph::SolverOptions o;
  o.robust_loss_scale = 0.0;
  const graph::CoarseCorrections C =
      graph::coarse_corrections(g.factors, g.poses, graph::make_key(gauge, kNoKeyframe), o, g.dimension);
  for (auto& [id, T] : estimate_) T = C.of(graph::make_key(me, id)) * T;
  for (auto& [k, T] : separators) T = C.of(k) * T;
  ++coarse_steps_;
  placed_by_peers_ = placed_by_peers_ || gauge < me;
  return {gauge};
}

// The group's gauge robot solves its block with no keyframe pinned (its peers' separator poses hold
// it), then moves rigidly so that its first keyframe is at its odometry pose: its odometry frame
// stays the group's frame, and the coarse step of the next round moves the others after it. A
// pinned keyframe would instead hold the map's bend about it, which the coarse step (one rigid move
// per robot) cannot remove. The move's rotation is projected onto SO(3): applied every round, a
// rounding error in it would otherwise grow from round to round.
void DistributedEstimate::hold_gauge(const LocalGraph& known) {
  const auto& [id, first] = *known.keyframes().begin();
  const auto e = estimate_.find(id);
  if (e == estimate_.end()) {
    return;
  }
  Eigen::Isometry3d G = first.T_odom * e->second.inverse();
  G.linear() = geometry::project_to_so3(G.linear());
  for (auto& [i, T] : estimate_) T = G * T;
}

// The own keyframes at the current estimate, their odometry, and every loop whose ends are both
// there: own keyframes, or peers' keyframes with a separator pose (held fixed).
DistributedEstimate::Problem DistributedEstimate::problem(const LocalGraph& known, const Separators& separators) const {
  const uint32_t me = known.robot();
  Problem p;
  for (const auto& [id, T] : estimate_) {
    p.graph.poses[graph::make_key(me, id)] = T;
  }
  known.add_odometry_factors(p.graph);
  for (const LoopRecord& l : known.loops()) {
    if (l.withdrawn) {
      continue;
    }
    const Key a = graph::make_key(l.robot_a, l.keyframe_a), b = graph::make_key(l.robot_b, l.keyframe_b);
    bool usable = true;
    for (Key k : {a, b}) {
      if (graph::robot_of(k) == me) {
        usable = usable && p.graph.poses.count(k) != 0;
      } else if (auto s = separators.find(k); s != separators.end()) {
        p.graph.poses[k] = s->second;
        p.fixed.insert(k);
        p.lowest = p.lowest && graph::robot_of(k) > me;
      } else {
        usable = false;
      }
    }
    if (usable) {
      p.graph.add_between(a, b, l.T_a_b, l.information);
    }
  }
  return p;
}

// The gauge: the central's last estimate when there is one; else, for the lowest robot of the
// group, its own odometry frame; otherwise the peers' separator poses hold it. After a coarse step
// the separator poses hold every robot (the gauge robot moves back after its solve, hold_gauge);
// only a robot with none of them in its problem pins its odometry frame.
void DistributedEstimate::anchor(Problem& p, const LocalGraph& known, const KeyframePoses& central,
                                 const Coarse& coarse) const {
  const uint32_t me = known.robot();
  for (auto it = central.rbegin(); it != central.rend(); ++it) {
    if (known.keyframes().count(it->first) != 0) {
      p.graph.add_prior(graph::make_key(me, it->first), it->second, Matrix6d::Identity() * kAnchorInformation);
      return;
    }
  }
  if (p.fixed.empty() || (p.lowest && !coarse.gauge)) {
    // The group's frame is this robot's odometry frame: the first keyframe is pinned to its odometry
    // pose (a constant; re-pinning it where the last round left it would let the gauge drift).
    const auto& [id, first] = *known.keyframes().begin();
    p.graph.add_prior(graph::make_key(me, id), first.T_odom, Matrix6d::Identity() * kAnchorInformation);
  }
}

void DistributedEstimate::solve(Problem& p) {
  if (config_.share_loop_information) {
    graph::share_loop_information(p.graph);
  }
  graph::SolverOptions o;
  o.max_iterations = config_.distributed_iterations;
  o.function_tolerance = 1e-8;
  // No Cauchy loss: in rounds that start misaligned it discounts exactly the loops that align the
  // robots, and the rounds converge many times more slowly. GNC from the least-squares solution
  // takes the own loops only (PeerConfig::own_loop_gnc_threshold).
  o.robust_loss_scale = 0.0;
  if (config_.own_loop_gnc_threshold > 0.0) {
    for (graph::Factor& f : p.graph.factors) f.robust = f.robust && !f.inter_robot();
    o.gnc.enabled = true;
    o.gnc.least_squares_start = true;
    o.gnc.inlier_threshold = config_.own_loop_gnc_threshold;
    o.gnc.mu_step = 2.0;
    o.gnc.max_rounds = kGncRounds;
  }
  const graph::SolveResult r = graph::solve(p.graph, o, p.fixed);
  if (r.gnc_converged && r.weights.size() == p.graph.factors.size()) {
    own_loops_held_out_ = 0;
    for (size_t i = 0; i < r.weights.size(); ++i) {
      if (p.graph.factors[i].robust && r.weights[i] < graph::kGncAcceptedWeight) ++own_loops_held_out_;
    }
  }
}

void DistributedEstimate::relax_towards(const graph::PoseGraph& solution) {
  for (auto& [id, T] : estimate_) {
    const Eigen::Isometry3d& S = solution.poses.at(graph::make_key(config_.robot, id));
    T = config_.relaxation == 1.0 ? S : T * geometry::se3_exp(config_.relaxation * geometry::se3_log(T.inverse() * S));
  }
}

}  // namespace cdc::peer
