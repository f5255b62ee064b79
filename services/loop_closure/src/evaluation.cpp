#include "cdc/loop_closure/evaluation.hpp"

#include <cmath>
#include <map>
#include <set>

namespace cdc::loops {

double LoopEvaluation::precision() const {
  return loops.empty() ? 1.0 : static_cast<double>(true_positives) / static_cast<double>(loops.size());
}

double LoopEvaluation::recall() const {
  return revisits == 0 ? 1.0 : static_cast<double>(recalled) / static_cast<double>(revisits);
}

LoopEvaluation evaluate_loops(const std::vector<TruthKeyframe>& order, const std::vector<LoopOut>& accepted,
                              const EvaluationOptions& o) {
  LoopEvaluation ev;
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::map<std::pair<uint32_t, uint32_t>, size_t> position;  // in the order the keyframes were made
  for (size_t i = 0; i < order.size(); ++i) {
    truth[{order[i].robot, order[i].id}] = order[i].T_world;
    position[{order[i].robot, order[i].id}] = i;
  }
  std::set<std::pair<uint32_t, uint32_t>> recalled;
  for (const LoopOut& l : accepted) {
    LoopVerdict v;
    v.loop = l;
    const auto a = truth.find({l.robot_a, l.keyframe_a}), b = truth.find({l.robot_b, l.keyframe_b});
    if (a != truth.end() && b != truth.end()) {
      const Eigen::Isometry3d e = (a->second.inverse() * b->second).inverse() * l.T_a_b;
      v.error_m = e.translation().norm();
      v.error_deg = Eigen::AngleAxisd(e.rotation()).angle() * 180.0 / M_PI;
      v.correct = v.error_m <= o.max_error_m && v.error_deg <= o.max_error_deg;
    }
    if (v.correct) {
      ++ev.true_positives;
      // The later of the two keyframes is the one that revisits (a robot's service may publish a
      // loop either way round: its own keyframe first, whichever is newer).
      const bool b_later = position.at({l.robot_b, l.keyframe_b}) > position.at({l.robot_a, l.keyframe_a});
      recalled.insert(b_later ? std::make_pair(l.robot_b, l.keyframe_b) : std::make_pair(l.robot_a, l.keyframe_a));
    } else {
      (l.robot_a == l.robot_b ? ev.false_intra : ev.false_inter) += 1;
    }
    ev.loops.push_back(v);
  }
  for (size_t i = 0; i < order.size(); ++i) {
    bool revisit = false;
    for (size_t j = 0; j < i && !revisit; ++j) {
      if (order[j].robot == order[i].robot && order[j].id + o.exclude_recent >= order[i].id) continue;
      revisit = (order[j].T_world.translation() - order[i].T_world.translation()).norm() <= o.revisit_m;
    }
    if (!revisit) continue;
    ++ev.revisits;
    if (recalled.count({order[i].robot, order[i].id}) != 0) {
      ++ev.recalled;
    } else {
      ev.missed.emplace_back(order[i].robot, order[i].id);
    }
  }
  return ev;
}

}  // namespace cdc::loops
