#include "cdc/peer_optimiser/separator_exchange.hpp"

#include "cdc/geometry/se3.hpp"

#include <utility>

namespace cdc::peer {

void SeparatorExchange::resend_to(uint32_t peer) {
  sent_.erase(peer);
  refreshed_.erase(peer);
  relayed_.erase(peer);
  view_sent_.erase(peer);
}

std::vector<SeparatorOut> SeparatorExchange::round(Nanos now, const std::map<uint32_t, std::set<uint32_t>>& wanted,
                                                   const std::map<uint32_t, Eigen::Isometry3d>& own,
                                                   const std::optional<Eigen::Isometry3d>& world_pose,
                                                   const std::map<uint32_t, std::vector<LoopRecord>>& relay,
                                                   CoarseView view) {
  std::set<uint32_t> peers;
  for (const auto& [peer, ids] : wanted) peers.insert(peer);
  for (const auto& [peer, loops] : relay) peers.insert(peer);
  std::vector<SeparatorOut> out;
  for (uint32_t peer : peers) {
    if (!uses_separators(peer, world_pose)) {
      resend_to(peer);  // all of them when it is back in range, or DISTRIBUTED
      continue;
    }
    const auto ids = wanted.find(peer);
    SeparatorOut s = poses_for(peer, now, ids != wanted.end() ? ids->second : std::set<uint32_t>{}, own);
    if (const auto loops = relay.find(peer); loops != relay.end()) s.loops = loops_for(peer, loops->second);
    s.inter_robot_loops = view.inter_robot_loops;
    s.coarse_step = view.coarse_step;
    const auto sent = view_sent_.find(peer);
    const bool view_changed = sent == view_sent_.end() || !(sent->second == view);
    if (!s.poses.empty() || !s.loops.empty() || view_changed) {
      view_sent_[peer] = view;
      out.push_back(std::move(s));
    }
  }
  return out;
}

std::vector<LoopRecord> SeparatorExchange::loops_for(uint32_t peer, const std::vector<LoopRecord>& loops) {
  auto& relayed = relayed_[peer];
  std::vector<LoopRecord> out;
  for (const LoopRecord& l : loops) {
    if (relayed.insert({l.sender, l.sender_incarnation, l.seq}).second) out.push_back(l);
  }
  return out;
}

bool SeparatorExchange::uses_separators(uint32_t peer, const std::optional<Eigen::Isometry3d>& world_pose) const {
  const auto position = peer_positions_.find(peer);
  const bool out_of_range = world_pose && position != peer_positions_.end() &&
                            (world_pose->translation() - position->second).norm() > config_.peer_range_m;
  const auto mode = peer_modes_.find(peer);
  const bool centralized = mode != peer_modes_.end() && mode->second == Mode::kCentralized;
  return !out_of_range && !centralized;
}

bool SeparatorExchange::moved(const Eigen::Isometry3d& before, const Eigen::Isometry3d& now) const {
  return (before.translation() - now.translation()).norm() >= config_.separator_min_change_m ||
         geometry::rotation_angle(before.linear().transpose() * now.linear()) >= config_.separator_min_change_rad;
}

SeparatorOut SeparatorExchange::poses_for(uint32_t peer, Nanos now, const std::set<uint32_t>& ids,
                                          const std::map<uint32_t, Eigen::Isometry3d>& own) {
  const auto refreshed = refreshed_.find(peer);
  const bool refresh = refreshed == refreshed_.end() || now - refreshed->second >= config_.separator_refresh;
  auto& sent = sent_[peer];
  SeparatorOut s;
  s.target = peer;
  for (uint32_t id : ids) {
    const auto it = own.find(id);
    if (it == own.end()) continue;
    const auto before = sent.find(id);
    if (refresh || before == sent.end() || moved(before->second, it->second)) {
      s.poses.emplace_back(id, it->second);
      sent[id] = it->second;
    }
  }
  if (refresh) refreshed_[peer] = now;
  return s;
}

}  // namespace cdc::peer
