#include "cdc/peer_optimiser/peer_core.hpp"

#include "cdc/geometry/alignment.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/graph/solver.hpp"

#include <algorithm>

namespace cdc::peer {
namespace {

constexpr double kAnchorInformation = 1e6;

}  // namespace

PeerCore::PeerCore(const PeerConfig& config, Nanos start) : config_(config), rtdos_(config.rtdos, start) {}

void PeerCore::add_keyframe(const OwnKeyframe& kf, Nanos now) {
  if (!keyframes_.emplace(kf.id, kf).second) {
    return;  // already held
  }
  keyframe_seen_[kf.id] = now;
  if (rtdos_.mode() == Mode::kDistributed) {
    auto prev = estimate_.find(kf.id - 1u);
    if (kf.id > 0 && prev != estimate_.end()) {
      estimate_[kf.id] = prev->second * kf.T_prev;
    }
  }
}

void PeerCore::add_loop(const LoopRecord& loop, Nanos now) {
  if (!loop_ids_.insert({loop.sender, loop.sender_incarnation, loop.seq}).second) {
    return;
  }
  loops_.push_back(loop);
  if (loop.sender == config_.robot) {
    own_loop_seen_[loop.seq] = now;
  }
}

void PeerCore::on_central_result(const CentralResult& r) {
  if (r.central_incarnation != central_incarnation_) {
    central_incarnation_ = r.central_incarnation;  // a (re)started central knows nothing yet
    relayed_newest_.reset();
    ack_ = AckIn{r.central_incarnation, 0, -1, -1};
  }
  central_ = r;
}

void PeerCore::on_ack(const AckIn& a) {
  const uint32_t mine = keyframes_.empty() ? a.robot_incarnation : keyframes_.rbegin()->second.incarnation;
  if (a.robot_incarnation != mine) {
    return;  // about an older incarnation of this robot
  }
  if (a.central_incarnation != central_incarnation_) {
    central_incarnation_ = a.central_incarnation;
  }
  ack_ = a;
}

void PeerCore::on_separator(uint32_t from, const std::vector<std::pair<uint32_t, Eigen::Isometry3d>>& poses) {
  for (const auto& [id, T] : poses) {
    separators_[graph::make_key(from, id)] = T;
  }
}

std::optional<Eigen::Isometry3d> PeerCore::world_pose() const {
  if (!published_ || keyframes_.empty()) {
    return std::nullopt;
  }
  return *published_ * keyframes_.rbegin()->second.T_odom;
}

std::map<uint32_t, Eigen::Isometry3d> complete_world_poses(const std::map<uint32_t, Eigen::Isometry3d>& T_odom,
                                                           const std::map<uint32_t, Eigen::Isometry3d>& corrected) {
  std::map<uint32_t, Eigen::Isometry3d> out;
  std::optional<Eigen::Isometry3d> T_world_odom;  // from the latest corrected keyframe seen
  for (const auto& [id, T] : T_odom) {
    auto c = corrected.find(id);
    if (c != corrected.end()) {
      T_world_odom = c->second * T.inverse();
      out[id] = c->second;
      continue;
    }
    if (!T_world_odom) {
      for (const auto& [cid, cT] : corrected) {  // the first corrected keyframe with odometry
        auto o = T_odom.find(cid);
        if (o != T_odom.end()) {
          T_world_odom = cT * o->second.inverse();
          break;
        }
      }
    }
    out[id] = T_world_odom.value_or(Eigen::Isometry3d::Identity()) * T;
  }
  return out;
}

std::optional<double> PeerCore::distance_to_central() const {
  const auto p = world_pose();
  if (!p || !central_position_) {
    return std::nullopt;
  }
  return (p->translation() - *central_position_).norm();
}

int64_t PeerCore::last_keyframe_id() const {
  return keyframes_.empty() ? int64_t{-1} : static_cast<int64_t>(keyframes_.rbegin()->first);
}

void PeerCore::ensure_initial_values() {
  std::map<uint32_t, Eigen::Isometry3d> central;
  if (central_) {
    central.insert(central_->poses.begin(), central_->poses.end());
  }
  for (const auto& [id, kf] : keyframes_) {
    if (estimate_.count(id) != 0) {
      continue;
    }
    if (auto c = central.find(id); c != central.end()) {
      estimate_[id] = c->second;
    } else if (auto prev = estimate_.find(id - 1); id > 0 && prev != estimate_.end()) {
      estimate_[id] = prev->second * kf.T_prev;
    } else {
      estimate_[id] = published_.value_or(Eigen::Isometry3d::Identity()) * kf.T_odom;
    }
  }
}

std::optional<Eigen::Isometry3d> PeerCore::distributed_round() {
  if (keyframes_.empty()) {
    return std::nullopt;
  }
  ensure_initial_values();
  const uint32_t me = config_.robot;
  // Without a central estimate, a robot that is not the lowest of its group starts in its own
  // odometry frame: place it rigidly through its most informative loop to a lower robot's
  // separator before solving (robust losses would otherwise discount exactly those loops).
  const bool have_central = central_ && !central_->poses.empty();
  if (!have_central && !placed_by_peers_) {
    const LoopRecord* best = nullptr;
    for (const LoopRecord& l : loops_) {
      const bool a_mine = l.robot_a == me, b_mine = l.robot_b == me;
      if (l.withdrawn || a_mine == b_mine) {
        continue;
      }
      const uint32_t other = a_mine ? l.robot_b : l.robot_a;
      const uint32_t other_kf = a_mine ? l.keyframe_b : l.keyframe_a;
      const uint32_t my_kf = a_mine ? l.keyframe_a : l.keyframe_b;
      if (other < me && separators_.count(graph::make_key(other, other_kf)) != 0 && estimate_.count(my_kf) != 0 &&
          (best == nullptr || l.information.trace() > best->information.trace())) {
        best = &l;
      }
    }
    if (best != nullptr) {
      const bool a_mine = best->robot_a == me;
      const Eigen::Isometry3d T_other =
          separators_.at(graph::make_key(a_mine ? best->robot_b : best->robot_a, a_mine ? best->keyframe_b : best->keyframe_a));
      const Eigen::Isometry3d T_other_mine = a_mine ? best->T_a_b.inverse() : best->T_a_b;
      const Eigen::Isometry3d T_mine = estimate_.at(a_mine ? best->keyframe_a : best->keyframe_b);
      const Eigen::Isometry3d correction = T_other * T_other_mine * T_mine.inverse();
      for (auto& [id, T] : estimate_) {
        T = correction * T;
      }
      placed_by_peers_ = true;
    }
  }
  graph::PoseGraph g;
  std::set<Key> fixed;
  for (const auto& [id, T] : estimate_) {
    g.poses[graph::make_key(me, id)] = T;
  }
  for (const auto& [id, kf] : keyframes_) {
    if (id > 0 && keyframes_.count(id - 1u) != 0) {
      g.add_between(graph::make_key(me, id - 1u), graph::make_key(me, id), kf.T_prev, kf.information);
    }
  }
  bool lowest = true;  // lowest robot id of the group this robot is tied to
  for (const LoopRecord& l : loops_) {
    if (l.withdrawn) {
      continue;
    }
    const Key a = graph::make_key(l.robot_a, l.keyframe_a), b = graph::make_key(l.robot_b, l.keyframe_b);
    bool usable = true;
    for (Key k : {a, b}) {
      if (graph::robot_of(k) == me) {
        usable = usable && g.poses.count(k) != 0;
      } else if (auto s = separators_.find(k); s != separators_.end()) {
        g.poses[k] = s->second;
        fixed.insert(k);
        lowest = lowest && graph::robot_of(k) > me;
      } else {
        usable = false;
      }
    }
    if (usable) {
      g.add_between(a, b, l.T_a_b, l.information);
    }
  }
  // Anchor: the central's last estimate when there is one; else, for the lowest robot of the
  // group, its own odometry frame; otherwise the peers' separator poses hold the gauge.
  std::optional<uint32_t> anchor;
  if (central_ && !central_->poses.empty()) {
    for (auto it = central_->poses.rbegin(); it != central_->poses.rend(); ++it) {
      if (keyframes_.count(it->first) != 0) {
        anchor = it->first;
        g.add_prior(graph::make_key(me, it->first), it->second, Matrix6d::Identity() * kAnchorInformation);
        break;
      }
    }
  }
  if (!anchor && (lowest || fixed.empty())) {
    // The group's frame is this robot's odometry frame: pin the first keyframe to its odometry
    // pose (a constant; re-pinning it where the last round left it would let the gauge drift).
    const auto& first = *keyframes_.begin();
    g.add_prior(graph::make_key(me, first.first), first.second.T_odom, Matrix6d::Identity() * kAnchorInformation);
  }
  if (g.factors.empty()) {
    return std::nullopt;
  }
  if (config_.share_loop_information) {
    graph::share_loop_information(g);
  }
  graph::SolverOptions o;
  o.max_iterations = config_.distributed_iterations;
  o.function_tolerance = 1e-8;
  // No robust loss here: loops reaching the back-end passed geometric verification and PCM, and
  // in rounds that start misaligned a robust kernel would discount exactly the loops that align
  // the robots (measured: 400 rounds without converging, against 40 with a plain cost).
  o.robust_loss_scale = 0.0;
  graph::solve(g, o, fixed);
  for (auto& [id, T] : estimate_) {
    const Eigen::Isometry3d& S = g.poses.at(graph::make_key(me, id));
    T = config_.relaxation == 1.0 ? S : T * geometry::se3_exp(config_.relaxation * geometry::se3_log(T.inverse() * S));
  }
  ++rounds_;
  return solution_world_transform(std::vector<std::pair<uint32_t, Eigen::Isometry3d>>(estimate_.begin(), estimate_.end()));
}

graph::PoseGraph PeerCore::graph() const {
  graph::PoseGraph g;
  const uint32_t me = config_.robot;
  for (const auto& [id, kf] : keyframes_) {
    const auto e = estimate_.find(id);
    g.poses[graph::make_key(me, id)] = e != estimate_.end() ? e->second : kf.T_odom;
    if (id > 0 && keyframes_.count(id - 1u) != 0) {
      g.add_between(graph::make_key(me, id - 1u), graph::make_key(me, id), kf.T_prev, kf.information);
    }
  }
  for (const auto& [k, T] : separators_) g.poses[k] = T;
  for (const LoopRecord& l : loops_) {
    const Key a = graph::make_key(l.robot_a, l.keyframe_a), b = graph::make_key(l.robot_b, l.keyframe_b);
    if (!l.withdrawn && g.poses.count(a) != 0 && g.poses.count(b) != 0) g.add_between(a, b, l.T_a_b, l.information);
  }
  return g;
}

std::optional<Eigen::Isometry3d> PeerCore::solution_world_transform(
    const std::vector<std::pair<uint32_t, Eigen::Isometry3d>>& poses) const {
  // T_world_robot as the central defines it: fitted to all the solution's own keyframes (paper eq. 1-2).
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> odom_world;
  odom_world.reserve(poses.size());
  for (const auto& [id, T] : poses) {
    if (const auto k = keyframes_.find(id); k != keyframes_.end()) odom_world.emplace_back(k->second.T_odom, T);
  }
  const geometry::Alignment a = geometry::align_poses(odom_world);
  if (!a.ok) return std::nullopt;
  return a.T_dst_src;
}

bool PeerCore::lowest_in_group() const {
  for (const LoopRecord& l : loops_) {
    if (!l.withdrawn && (l.robot_a < config_.robot || l.robot_b < config_.robot) &&
        (l.robot_a == config_.robot || l.robot_b == config_.robot)) {
      return false;  // tied by a loop to a lower robot
    }
  }
  return true;
}

StepOutput PeerCore::step(Nanos now, bool central_alive) {
  StepOutput out;
  out.transition = rtdos_.update(RtdosInput{now, central_alive, distance_to_central()});
  const Mode mode = rtdos_.mode();
  if (out.transition && mode == Mode::kDistributed) {
    estimate_.clear();  // start from the central's last estimate (paper III-A-2)
    ensure_initial_values();
    last_round_ = Nanos{0};
  }
  if (out.transition && mode == Mode::kCentralized) {
    rejoining_ = true;
    if (target_) {
      out.world_transform = target_;  // the central starts from the distributed estimate
    }
    // The central's estimate of this robot is current once it holds every keyframe made so far:
    // until then its last result is from before the cut (or a graph still taking in the re-sent
    // backlog), and relaying it would pull the front-end back to where the robot was then.
    frontier_.reset();
    if (!keyframes_.empty()) frontier_ = keyframes_.rbegin()->first;
  }
  // A result holding fewer of this robot's keyframes than one already relayed is partial too: the
  // central placing the robot anew (its first loop after a rejoin), with a gap in the re-sent backlog
  // it fills in order. Relaying it carried the correction back to an old keyframe and out again with a
  // different placement: robot 2 of the demo 0.3 m off for 0.8 s. Wait until it catches up.
  // A placement from the robot's own hint (the central has not put it in its graph yet) holds every
  // keyframe but no correction: relaying it took the front-end back to its bare odometry, then to the
  // stale distributed estimate once a placed result with part of the backlog came, then to the central's
  // (three sources in a few seconds after a rejoin, session 19's debug run). It is not relayed and does
  // not count towards the frontier: the distributed estimate stays until a placed result is current.
  std::optional<uint32_t> central_newest;  // the newest own keyframe the central's last result holds
  if (central_ && !central_->from_hint) {
    for (const auto& p : central_->poses) central_newest = std::max(central_newest.value_or(0), p.first);
  }
  if (!frontier_ && central_newest && relayed_newest_ && *central_newest < *relayed_newest_) {
    frontier_ = *relayed_newest_;
  }
  if (frontier_ && central_newest && *central_newest >= *frontier_) {
    frontier_.reset();
  }
  const bool central_current = central_.has_value() && !central_->from_hint && !frontier_;
  if (central_current && central_newest) {
    relayed_newest_ = std::max(relayed_newest_.value_or(0), *central_newest);
  }

  const bool round_due = now - last_round_ >= config_.round_period;
  if (mode == Mode::kCentralized) {
    if (central_current) {
      target_ = central_->T_world_robot;
    }
    if (central_alive && (rejoining_ || now - last_resend_ >= config_.resend_period)) {
      // At most max_resend_per_step a step, so that a long backlog goes out over several resend
      // periods while the node's loop keeps running; what is sent waits resend_grace again.
      const auto pick = [&](std::map<uint32_t, Nanos>& seen_at, int64_t acked, std::vector<uint32_t>& resend) {
        for (auto& [id, seen] : seen_at) {
          if (resend.size() >= config_.max_resend_per_step) break;
          if (static_cast<int64_t>(id) > acked && (rejoining_ || now - seen >= config_.resend_grace)) {
            resend.push_back(id);
            seen = now;
          }
        }
      };
      pick(keyframe_seen_, ack_.keyframe, out.resend_keyframes);
      pick(own_loop_seen_, ack_.loop_seq, out.resend_loops);
      rejoining_ = false;
      last_resend_ = now;
    }
  } else if (round_due) {
    const auto T = distributed_round();
    // Only an estimate in W becomes a correction: W is known from the central, by being robot 0
    // (its odometry frame is W), or through a peer's separators. Before that the robot has no world
    // pose, and its first real estimate is an initialisation, not a correction to limit.
    const bool in_world = (central_ && !central_->poses.empty()) || config_.robot == 0 || placed_by_peers_;
    if (T && in_world) {
      target_ = *T;
    }
  }

  // Separators for DISTRIBUTED peers in range: the poses of own keyframes that their loops touch. A robot
  // sends them only once its estimate is in the group's frame (central estimate, lowest robot of
  // its group, or placed through a peer), so that it never drags its neighbours into its own frame.
  const bool in_group_frame = (central_ && !central_->poses.empty()) || placed_by_peers_ || lowest_in_group();
  if (round_due) {
    last_round_ = now;
  }
  if (round_due && in_group_frame) {
    std::map<uint32_t, Eigen::Isometry3d> own;
    if (mode == Mode::kCentralized && central_) {
      own.insert(central_->poses.begin(), central_->poses.end());
    } else {
      own = estimate_;
    }
    std::map<uint32_t, std::set<uint32_t>> wanted;  // target robot -> own keyframe ids
    for (const LoopRecord& l : loops_) {
      if (l.withdrawn || l.robot_a == l.robot_b) {
        continue;
      }
      if (l.robot_a == config_.robot) {
        wanted[l.robot_b].insert(l.keyframe_a);
      } else if (l.robot_b == config_.robot) {
        wanted[l.robot_a].insert(l.keyframe_b);
      }
    }
    const auto me = world_pose();
    for (const auto& [target, ids] : wanted) {
      auto peer = peer_positions_.find(target);
      const bool out_of_range =
          me && peer != peer_positions_.end() && (me->translation() - peer->second).norm() > config_.peer_range_m;
      const auto peer_mode = peer_modes_.find(target);
      const bool centralized = peer_mode != peer_modes_.end() && peer_mode->second == Mode::kCentralized;
      if (out_of_range || centralized) {
        // Out of radio range of that peer, or it does not use them now: all of them when it is
        // back, or DISTRIBUTED.
        separators_sent_.erase(target);
        separators_refreshed_.erase(target);
        continue;
      }
      auto refreshed = separators_refreshed_.find(target);
      const bool refresh = refreshed == separators_refreshed_.end() || now - refreshed->second >= config_.separator_refresh;
      auto& sent = separators_sent_[target];
      SeparatorOut s;
      s.target = target;
      for (uint32_t id : ids) {
        const auto it = own.find(id);
        if (it == own.end()) continue;
        const auto before = sent.find(id);
        const bool moved = before == sent.end() ||
                           (before->second.translation() - it->second.translation()).norm() >= config_.separator_min_change_m ||
                           geometry::rotation_angle(before->second.linear().transpose() * it->second.linear()) >=
                               config_.separator_min_change_rad;
        if (refresh || moved) {
          s.poses.emplace_back(id, it->second);
          sent[id] = it->second;
        }
      }
      if (refresh) separators_refreshed_[target] = now;
      if (!s.poses.empty()) {
        out.separators.push_back(std::move(s));
      }
    }
  }

  // The correction the front-end gets: never more than the fusion thresholds per step.
  if (target_) {
    Correction c;
    if (!published_) {
      published_ = *target_;
    } else {
      const geometry::FusionResult f = geometry::fuse_pose(*published_, *target_, config_.fusion);
      published_ = f.fused;
      c.lambda = f.lambda;
    }
    c.T_world_robot = *published_;
    c.from_central = mode == Mode::kCentralized && central_current;
    if (c.from_central) {
      c.poses = central_->poses;
    } else {
      c.poses.assign(estimate_.begin(), estimate_.end());
    }
    // The poses go out in the frame of the T_world_robot sent with them: the solution moved by the
    // same bounded step, so that T_world_robot^-1 * pose (what the front-end takes) is the solution's
    // own. A newer solution's poses under a T_world_robot still on its way put the front-end off by
    // the step still to go times the distance from the robot's first keyframe (robot 2 of the demo:
    // 0.3-0.4 m of height for 1.5 s after a rejoin, while the central's own estimate was steady).
    if (const auto solution_T_world_robot = solution_world_transform(c.poses)) {
      const Eigen::Isometry3d to_sent = c.T_world_robot * solution_T_world_robot->inverse();
      for (auto& [id, T] : c.poses) T = to_sent * T;
    }
    out.correction = std::move(c);
  }
  return out;
}

}  // namespace cdc::peer
