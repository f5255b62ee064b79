#include "cdc/peer_optimiser/local_graph.hpp"

#include "cdc/geometry/alignment.hpp"

#include <algorithm>
#include <utility>

namespace cdc::peer {

bool LocalGraph::add_keyframe(const OwnKeyframe& kf) { return keyframes_.emplace(kf.id, kf).second; }

bool LocalGraph::add_loop(const LoopRecord& loop) {
  if (!loop_ids_.insert({loop.sender, loop.sender_incarnation, loop.seq}).second) {
    return false;
  }
  loops_.push_back(loop);
  return true;
}

bool LocalGraph::add_group_loop(const LoopRecord& loop) {
  if (loop.robot_a == loop.robot_b || loop.robot_a == robot_ || loop.robot_b == robot_ ||
      !loop_ids_.insert({loop.sender, loop.sender_incarnation, loop.seq}).second) {
    return false;
  }
  group_loops_.push_back(loop);
  return true;
}

std::vector<const LoopRecord*> LocalGraph::inter_robot_loops() const {
  using Ends = std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>;
  std::set<Ends> withdrawn;
  std::vector<const LoopRecord*> all;
  for (const auto* list : {&loops_, &group_loops_}) {
    for (const LoopRecord& l : *list) {
      if (l.robot_a == l.robot_b) continue;
      if (l.withdrawn) {
        withdrawn.insert({l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b});
      } else {
        all.push_back(&l);
      }
    }
  }
  std::vector<const LoopRecord*> out;
  for (const LoopRecord* l : all) {
    if (withdrawn.count({l->robot_a, l->keyframe_a, l->robot_b, l->keyframe_b}) == 0) out.push_back(l);
  }
  return out;
}

std::set<uint32_t> LocalGraph::group() const {
  std::set<uint32_t> reached{robot_};
  const std::vector<const LoopRecord*> links = inter_robot_loops();
  for (bool grew = true; grew;) {
    grew = false;
    for (const LoopRecord* l : links) {
      const bool a = reached.count(l->robot_a) != 0, b = reached.count(l->robot_b) != 0;
      if (a != b) {
        reached.insert(a ? l->robot_b : l->robot_a);
        grew = true;
      }
    }
  }
  reached.erase(robot_);
  return reached;
}

std::map<uint32_t, std::set<uint32_t>> LocalGraph::group_separator_ids() const {
  std::set<uint32_t> ids;
  for (const LoopRecord* l : inter_robot_loops()) {
    if (l->robot_a == robot_) ids.insert(l->keyframe_a);
    if (l->robot_b == robot_) ids.insert(l->keyframe_b);
  }
  std::map<uint32_t, std::set<uint32_t>> wanted;
  for (uint32_t peer : group()) wanted[peer] = ids;
  return wanted;
}

std::map<uint32_t, std::vector<LoopRecord>> LocalGraph::loops_to_relay() const {
  std::map<uint32_t, std::vector<LoopRecord>> out;
  for (uint32_t peer : group()) {
    for (const LoopRecord& l : loops_) {
      if (l.robot_a != l.robot_b && std::min(l.robot_a, l.robot_b) == robot_ && l.robot_a != peer &&
          l.robot_b != peer) {
        out[peer].push_back(l);
      }
    }
  }
  return out;
}

uint32_t LocalGraph::inter_robot_loops_of(uint32_t robot) const {
  const std::vector<const LoopRecord*> loops = inter_robot_loops();
  return static_cast<uint32_t>(std::count_if(
      loops.begin(), loops.end(), [&](const LoopRecord* l) { return l->robot_a == robot || l->robot_b == robot; }));
}

bool LocalGraph::shares_coarse_step_with(uint32_t robot) const {
  if (robot == robot_) return true;
  const auto said = coarse_views_.find(robot);
  return said != coarse_views_.end() && said->second.second && inter_robot_loops_of(robot) == said->second.first;
}

void LocalGraph::on_separator(uint32_t from, const KeyframePoses& poses) {
  for (const auto& [id, T] : poses) {
    separators_[graph::make_key(from, id)] = T;
  }
}

std::optional<uint32_t> LocalGraph::newest_id() const {
  if (keyframes_.empty()) return std::nullopt;
  return keyframes_.rbegin()->first;
}

std::map<uint32_t, std::set<uint32_t>> LocalGraph::separator_ids() const {
  std::map<uint32_t, std::set<uint32_t>> wanted;  // target robot -> own keyframe ids
  for (const LoopRecord& l : loops_) {
    if (l.withdrawn || l.robot_a == l.robot_b) {
      continue;
    }
    if (l.robot_a == robot_) {
      wanted[l.robot_b].insert(l.keyframe_a);
    } else if (l.robot_b == robot_) {
      wanted[l.robot_a].insert(l.keyframe_b);
    }
  }
  return wanted;
}

bool LocalGraph::lowest_in_group() const {
  for (const LoopRecord& l : loops_) {
    if (!l.withdrawn && (l.robot_a < robot_ || l.robot_b < robot_) && (l.robot_a == robot_ || l.robot_b == robot_)) {
      return false;  // tied by a loop to a lower robot
    }
  }
  return true;
}

void LocalGraph::add_odometry_factors(graph::PoseGraph& g) const {
  for (const auto& [id, kf] : keyframes_) {
    if (id > 0 && keyframes_.count(id - 1u) != 0) {
      g.add_between(graph::make_key(robot_, id - 1u), graph::make_key(robot_, id), kf.T_prev, kf.information);
    }
  }
}

std::optional<Eigen::Isometry3d> LocalGraph::world_transform_of(const KeyframePoses& poses) const {
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> odom_world;
  odom_world.reserve(poses.size());
  for (const auto& [id, T] : poses) {
    if (const auto k = keyframes_.find(id); k != keyframes_.end()) odom_world.emplace_back(k->second.T_odom, T);
  }
  const geometry::Alignment a = geometry::align_poses(odom_world);
  if (!a.ok) return std::nullopt;
  return a.T_dst_src;
}

graph::PoseGraph LocalGraph::graph(const std::map<uint32_t, Eigen::Isometry3d>& estimate) const {
  graph::PoseGraph g;
  for (const auto& [id, kf] : keyframes_) {
    const auto e = estimate.find(id);
    g.poses[graph::make_key(robot_, id)] = e != estimate.end() ? e->second : kf.T_odom;
  }
  add_odometry_factors(g);
  for (const auto& [k, T] : separators_) g.poses[k] = T;
  for (const LoopRecord& l : loops_) {
    const Key a = graph::make_key(l.robot_a, l.keyframe_a), b = graph::make_key(l.robot_b, l.keyframe_b);
    if (!l.withdrawn && g.poses.count(a) != 0 && g.poses.count(b) != 0) g.add_between(a, b, l.T_a_b, l.information);
  }
  return g;
}

}  // namespace cdc::peer
