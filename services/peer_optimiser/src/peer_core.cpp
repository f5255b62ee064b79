#include "cdc/peer_optimiser/peer_core.hpp"

#include "cdc/geometry/fusion.hpp"

#include <utility>

namespace cdc::peer {

PeerCore::PeerCore(const PeerConfig& config, Nanos start)
    : config_(config),
      rtdos_(config.rtdos, start),
      known_(config.robot),
      backlog_(config),
      separators_(config),
      distributed_(config) {}

KeyframeAdmission PeerCore::add_keyframe(const OwnKeyframe& kf, Nanos now) {
  const auto held = known_.keyframes().find(kf.id);
  if (held != known_.keyframes().end() && held->second.incarnation == kf.incarnation &&
      held->second.stamp_ns == kf.stamp_ns) {
    ++keyframe_counters_.duplicate;
    return {Admission::kDuplicate, {}};
  }
  if (std::optional<std::string> reason = conflict(kf)) {
    ++keyframe_counters_.refused;
    return {Admission::kRefused, std::move(*reason)};
  }
  known_.add_keyframe(kf);
  backlog_.add_keyframe(kf.id, now);
  if (mode() == Mode::kDistributed) {
    distributed_.extend(kf);
  }
  return {};
}

// Why a keyframe that is not a duplicate cannot join the robot's sequence, if it cannot: its id is
// held already (a front-end that numbered afresh), or it belongs to another sequence.
std::optional<std::string> PeerCore::conflict(const OwnKeyframe& kf) const {
  const OwnKeyframe* newest = newest_keyframe();
  if (newest == nullptr) return std::nullopt;  // the first keyframe starts the sequence
  const std::string what = "robot " + std::to_string(config_.robot) + " keyframe " + std::to_string(kf.id) +
                           " of incarnation " + std::to_string(kf.incarnation) + " (stamp " +
                           std::to_string(kf.stamp_ns) + " ns)";
  const std::string restart = "; a restarted front-end continues after keyframe " + std::to_string(newest->id) +
                              " of incarnation " + std::to_string(newest->incarnation);
  const auto held = known_.keyframes().find(kf.id);
  if (held != known_.keyframes().end()) {
    return what + ": id held already from incarnation " + std::to_string(held->second.incarnation) + " (stamp " +
           std::to_string(held->second.stamp_ns) + " ns) with other contents" + restart;
  }
  if (kf.incarnation != newest->incarnation) {
    return what + ": not of the keyframe sequence held (incarnation " + std::to_string(newest->incarnation) + ")" +
           restart;
  }
  return std::nullopt;
}

const OwnKeyframe* PeerCore::newest_keyframe() const {
  const auto& keyframes = known_.keyframes();
  return keyframes.empty() ? nullptr : &keyframes.rbegin()->second;
}

const OwnKeyframe* PeerCore::keyframe(uint32_t id) const {
  const auto it = known_.keyframes().find(id);
  return it == known_.keyframes().end() ? nullptr : &it->second;
}

geometry::Trajectory PeerCore::world_trajectory() const {
  std::map<uint32_t, Eigen::Isometry3d> T_odom;
  for (const auto& [id, k] : known_.keyframes()) T_odom[id] = k.T_odom;
  geometry::Trajectory trajectory;
  for (const auto& [id, T] : complete_world_poses(T_odom, corrected_)) {
    trajectory.push_back({known_.keyframes().at(id).stamp_ns, T});
  }
  return trajectory;
}

void PeerCore::add_loop(const LoopRecord& loop, Nanos now) {
  if (known_.add_loop(loop) && loop.sender == config_.robot) {
    backlog_.add_own_loop(loop.seq, now);
  }
}

void PeerCore::on_separator(uint32_t from, const SeparatorOut& message) {
  known_.on_separator(from, message.poses);
  for (const LoopRecord& l : message.loops) known_.add_group_loop(l);
  known_.on_coarse_view(from, message.inter_robot_loops, message.coarse_step);
}

void PeerCore::on_central_result(const CentralResult& r) {
  if (r.central_incarnation != central_incarnation_) {
    central_incarnation_ = r.central_incarnation;  // a (re)started central knows nothing yet
    central_.forget_relayed();
    backlog_.forget_acknowledgements(r.central_incarnation);
  }
  central_.on_result(r);
}

void PeerCore::on_ack(const AckIn& a) {
  const auto& keyframes = known_.keyframes();
  const uint32_t mine = keyframes.empty() ? a.robot_incarnation : keyframes.rbegin()->second.incarnation;
  if (a.robot_incarnation != mine) {
    return;  // about an older incarnation of this robot
  }
  central_incarnation_ = a.central_incarnation;
  backlog_.on_ack(a);
}

std::optional<Eigen::Isometry3d> PeerCore::world_pose() const {
  const auto& keyframes = known_.keyframes();
  if (!published_ || keyframes.empty()) {
    return std::nullopt;
  }
  return *published_ * keyframes.rbegin()->second.T_odom;
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
  const auto newest = known_.newest_id();
  return newest ? static_cast<int64_t>(*newest) : int64_t{-1};
}

graph::PoseGraph PeerCore::graph() const { return known_.graph(distributed_.poses()); }

StepOutput PeerCore::step(Nanos now, bool central_alive) {
  StepOutput out;
  out.transition = rtdos_.update(RtdosInput{now, central_alive, distance_to_central()});
  if (out.transition && out.transition->to == Mode::kDistributed) {
    enter_distributed(out);
  } else if (out.transition) {
    enter_centralized(out);
  }
  const bool central_current = central_.update();
  const bool round_due = now - last_round_ >= config_.round_period;
  if (mode() == Mode::kCentralized) {
    if (central_current) {
      target_ = central_.last()->T_world_robot;
    }
    CentralBacklog::Resend resend = backlog_.due(now, central_alive);
    out.resend_keyframes = std::move(resend.keyframes);
    out.resend_loops = std::move(resend.loops);
  } else if (round_due) {
    follow_distributed_round();
  }
  if (round_due) {
    last_round_ = now;
    out.separators = separators_due(now);
    for (const SeparatorOut& s : out.separators) {
      traffic_.poses += s.poses.size();
      traffic_.loops += s.loops.size();
    }
  }
  if (target_) {
    out.correction = next_correction(mode() == Mode::kCentralized && central_current);
  }
  return out;
}

// The distributed rounds start from the central's last estimate (paper III-A-2), at once.
void PeerCore::enter_distributed(StepOutput& out) {
  distributed_.clear();
  distributed_.seed(known_, central_.poses(), published_);
  last_round_ = Nanos{0};
  out.drop_undelivered_keyframes = true;
}

// The central starts from the distributed estimate; it gets every keyframe and own loop it has not
// acknowledged, and its results are relayed again once it holds the newest keyframe made so far.
void PeerCore::enter_centralized(StepOutput& out) {
  backlog_.on_rejoin();
  out.world_transform = target_;
  central_.on_rejoin(known_.newest_id());
}

// Only an estimate in W becomes a correction: W is known from the central, by being robot 0 (its
// odometry frame is W), or through a peer's separators. Before that the robot has no world pose,
// and its first real estimate is an initialisation, not a correction to limit.
void PeerCore::follow_distributed_round() {
  const auto T_world_robot = distributed_.round(known_, central_.poses(), published_);
  const bool in_world = central_.has_poses() || config_.robot == 0 || distributed_.placed_by_peers();
  if (T_world_robot && in_world) {
    target_ = *T_world_robot;
  }
}

// A robot sends separator poses only once its estimate is in its group's frame (the central's
// estimate, the lowest robot of its group, or placed through peers), so that it never drags its
// neighbours into its own frame. They carry the central's poses while CENTRALIZED, else the
// distributed estimate. With the coarse step every robot of the group gets the poses of every own
// keyframe an inter-robot loop touches, and the loops it relays (those go in any frame).
std::vector<SeparatorOut> PeerCore::separators_due(Nanos now) {
  const bool in_frame = central_.has_poses() || distributed_.placed_by_peers() || known_.lowest_in_group();
  const bool from_central = mode() == Mode::kCentralized && central_.last();
  std::map<uint32_t, Eigen::Isometry3d> own;
  if (from_central) {
    own.insert(central_.poses().begin(), central_.poses().end());
  } else if (in_frame) {
    own = distributed_.poses();
  }
  if (!config_.coarse_step) {
    return in_frame ? separators_.round(now, known_.separator_ids(), own, world_pose()) : std::vector<SeparatorOut>{};
  }
  const bool coarse = mode() == Mode::kDistributed && central_.poses().empty();
  return separators_.round(now, known_.group_separator_ids(), own, world_pose(), known_.loops_to_relay(),
                           {known_.inter_robot_loops_of(config_.robot), coarse});
}

// The correction the front-end gets: never more than the fusion thresholds per step.
Correction PeerCore::next_correction(bool from_central) {
  Correction c;
  if (!published_) {
    published_ = *target_;
  } else {
    const geometry::FusionResult f = geometry::fuse_pose(*published_, *target_, config_.fusion);
    published_ = f.fused;
    c.lambda = f.lambda;
  }
  c.T_world_robot = *published_;
  c.from_central = from_central;
  if (from_central) {
    c.poses = central_.poses();
  } else {
    c.poses.assign(distributed_.poses().begin(), distributed_.poses().end());
  }
  // The poses go out in the frame of the T_world_robot sent with them: the solution moved by the
  // same bounded step, so that T_world_robot^-1 * pose (what the front-end takes) is the solution's
  // own. A newer solution's poses under a T_world_robot still on its way would put the front-end off
  // by the step still to go times the distance from the robot's first keyframe.
  if (const auto solution_T_world_robot = known_.world_transform_of(c.poses)) {
    const Eigen::Isometry3d to_sent = c.T_world_robot * solution_T_world_robot->inverse();
    for (auto& [id, T] : c.poses) T = to_sent * T;
  }
  for (const auto& [id, T] : c.poses) corrected_[id] = T;
  return c;
}

}  // namespace cdc::peer
