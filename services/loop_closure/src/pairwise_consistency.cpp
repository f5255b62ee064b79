#include "cdc/loop_closure/pairwise_consistency.hpp"

#include "cdc/graph/pcm.hpp"

#include <algorithm>

namespace cdc::loops {

void PairwiseConsistency::add_odometry(uint32_t robot, uint32_t from, uint32_t to, const Eigen::Isometry3d& T,
                                       const graph::Matrix6d& info) {
  graph_.add_between(graph::make_key(robot, from), graph::make_key(robot, to), T, info);
}

void PairwiseConsistency::add_keyframe_odometry(uint32_t robot, uint32_t id, const Eigen::Isometry3d& T_prev,
                                                const graph::Matrix6d& information) {
  if (id > 0) {
    add_odometry(robot, id - 1u, id, T_prev, information);
  }
  data_robots_.insert(robot);
}

void PairwiseConsistency::add_pose_hint(uint32_t robot, uint32_t id, const Eigen::Isometry3d& pose_hint) {
  if (data_robots_.count(robot) != 0) return;
  auto it = last_hint_.find(robot);
  if (it != last_hint_.end() && it->second.first < id) {
    const Eigen::Isometry3d T = it->second.second.inverse() * pose_hint;
    const double len = T.translation().norm();
    const double st = p_.hint_sigma_m + p_.hint_sigma_m_per_m * len;
    const double sr = p_.hint_sigma_rad + p_.hint_sigma_rad_per_m * len;
    graph::Matrix6d info = graph::Matrix6d::Zero();
    info.diagonal() << 1 / (st * st), 1 / (st * st), 1 / (st * st), 1 / (sr * sr), 1 / (sr * sr), 1 / (sr * sr);
    add_odometry(robot, it->second.first, id, T, info);
  }
  if (it == last_hint_.end() || it->second.first < id) {
    last_hint_[robot] = {id, pose_hint};
  }
}

std::vector<LoopOut> PairwiseConsistency::add_loop(const LoopOut& loop) {
  return loop.robot_a == loop.robot_b ? add_intra(loop) : add_inter(loop);
}

std::vector<LoopOut> PairwiseConsistency::add_intra(const LoopOut& loop) {
  graph::Factor f;
  f.kind = graph::FactorKind::kLoop;
  f.a = graph::make_key(loop.robot_a, loop.keyframe_a);
  f.b = graph::make_key(loop.robot_b, loop.keyframe_b);
  f.measurement = loop.T_a_b;
  f.information = loop.information;
  // It must agree with the robot's own odometry between the two keyframes.
  if (graph::Pcm::odometry_distance(graph_, f) > p_.pcm.chi2_threshold) {
    ++stats_.intra_inconsistent;
    return {};
  }
  ++stats_.intra_accepted;
  graph_.add_between(f.a, f.b, loop.T_a_b, loop.information);
  return {loop};
}

std::vector<LoopOut> PairwiseConsistency::add_inter(const LoopOut& loop) {
  ++stats_.inter_proposed;
  graph_.add_between(graph::make_key(loop.robot_a, loop.keyframe_a), graph::make_key(loop.robot_b, loop.keyframe_b),
                     loop.T_a_b, loop.information);
  const size_t id = graph_.factors.size() - 1;
  const RobotPair pair{std::min(loop.robot_a, loop.robot_b), std::max(loop.robot_a, loop.robot_b)};
  inter_[pair].push_back(id);
  proposed_[id] = loop;
  return publish(pair, publishable(pair));
}

std::set<size_t> PairwiseConsistency::publishable(const RobotPair& pair) {
  const auto [a, b] = pair;
  // PCM over this pair only: both robots' odometry and the pair's proposed loops.
  graph::PoseGraph g;
  const std::vector<size_t>& ids = inter_[pair];
  for (const graph::Factor& f : graph_.factors) {
    if (f.kind == graph::FactorKind::kOdometry && (graph::robot_of(f.a) == a || graph::robot_of(f.a) == b)) {
      g.factors.push_back(f);
    }
  }
  const size_t first_loop = g.factors.size();
  for (size_t f : ids) {
    g.factors.push_back(graph_.factors[f]);
  }
  const graph::OutlierDecision d = graph::Pcm(p_.pcm).decide(g);
  // The consistent set is published when it is large enough and rests on more than one keyframe of
  // each robot: loops sharing a keyframe share its cloud, and a registration that slid along a
  // featureless stretch slides the same way for all of them (consistent, and wrong together).
  std::set<uint32_t> keyframes_a, keyframes_b;
  for (size_t i : d.accepted) {
    const LoopOut& l = proposed_.at(ids[i - first_loop]);
    keyframes_a.insert(l.robot_a == a ? l.keyframe_a : l.keyframe_b);
    keyframes_b.insert(l.robot_a == a ? l.keyframe_b : l.keyframe_a);
  }
  const size_t distinct = std::min<size_t>(2, p_.min_inter_support);
  std::set<size_t> accepted;
  if (d.accepted.size() >= p_.min_inter_support && keyframes_a.size() >= distinct && keyframes_b.size() >= distinct) {
    for (size_t i : d.accepted) accepted.insert(ids[i - first_loop]);
  }
  return accepted;
}

std::vector<LoopOut> PairwiseConsistency::publish(const RobotPair& pair, const std::set<size_t>& accepted) {
  std::vector<LoopOut> out;
  for (size_t f : inter_[pair]) {
    const bool now = accepted.count(f) != 0, before = published_.count(f) != 0;
    if (now && !before) {
      published_.insert(f);
      ++stats_.inter_accepted;
      out.push_back(proposed_[f]);
    } else if (!now && before) {
      published_.erase(f);
      ++stats_.withdrawn;
      LoopOut w = proposed_[f];
      w.withdrawn = true;
      out.push_back(w);
    }
  }
  return out;
}

}  // namespace cdc::loops
