#include "cdc/loop_closure/peer_reach.hpp"

#include <algorithm>
#include <set>

namespace cdc::loops {

bool PeerReach::in_reach(uint32_t robot, Nanos now) const {
  if (robot == me_) return true;
  const auto it = last_heard_.find(robot);
  return it != last_heard_.end() && now - it->second <= p_.silence;
}

void PeerReach::heard(uint32_t peer, Nanos now) {
  if (peer == me_) return;
  const auto it = last_heard_.find(peer);
  if (it != last_heard_.end() && now - it->second > p_.silence) {
    ++stats_.silences;
    const Nanos since = it->second - p_.margin;
    const auto [c, fresh] = catchup_.try_emplace(peer, Catchup{since, now + p_.delay});
    if (!fresh) {  // silent again before the last catch-up went out: it covers both silences
      c->second.since = std::min(c->second.since, since);
      c->second.at = now + p_.delay;
    }
  }
  if (it == last_heard_.end() || now > it->second) last_heard_[peer] = now;
}

std::optional<uint64_t> PeerReach::published(uint64_t id, uint32_t robot_a, uint32_t keyframe_a, uint32_t robot_b,
                                             uint32_t keyframe_b, bool withdrawal, Nanos now) {
  if (withdrawal) {
    for (Written& w : written_) {
      if (!w.withdrawal && w.robot_a == robot_a && w.keyframe_a == keyframe_a && w.robot_b == robot_b &&
          w.keyframe_b == keyframe_b) {
        w.withdrawn = true;
      }
    }
  }
  written_.push_back({id, robot_a, keyframe_a, robot_b, keyframe_b, withdrawal, now});
  if (written_.size() <= p_.keep) return std::nullopt;
  const uint64_t gone = written_.front().id;
  written_.pop_front();
  ++stats_.forgotten;
  return gone;
}

std::vector<uint64_t> PeerReach::due(Nanos now) {
  std::set<uint64_t> ids;
  for (auto c = catchup_.begin(); c != catchup_.end();) {
    if (c->second.at > now) {
      ++c;
      continue;
    }
    const uint32_t peer = c->first;
    // written_ is in time order: the loops since the silence began are its tail.
    auto from = std::lower_bound(written_.begin(), written_.end(), c->second.since,
                                 [](const Written& w, Nanos t) { return w.at < t; });
    for (; from != written_.end(); ++from) {
      if (!from->withdrawn && (from->robot_a == peer || from->robot_b == peer)) ids.insert(from->id);
    }
    c = catchup_.erase(c);
  }
  stats_.loops_due += ids.size();
  return {ids.begin(), ids.end()};
}

}  // namespace cdc::loops
