#include "cdc/loop_closure/descriptor_sequencer.hpp"

namespace cdc::loops {

void DescriptorSequencer::drain(Stream& s, std::vector<DescriptorIn>& out) {
  for (auto it = s.ahead.begin(); it != s.ahead.end() && it->first == s.next; it = s.ahead.erase(it)) {
    out.push_back(std::move(it->second));
    ++s.next;
    ++stats_.delivered;
  }
}

void DescriptorSequencer::skip_gap(Stream& s, std::vector<DescriptorIn>& out) {
  if (s.ahead.empty()) return;
  ++stats_.gaps_skipped;
  stats_.ids_skipped += s.ahead.begin()->first - s.next;
  s.next = s.ahead.begin()->first;
  s.attempts = 0;
  drain(s, out);
}

std::vector<DescriptorIn> DescriptorSequencer::add(DescriptorIn d) {
  std::vector<DescriptorIn> out;
  Stream& s = streams_[d.robot];
  if (d.id < s.next || s.ahead.count(d.id) != 0) {
    ++stats_.duplicates;
    return out;
  }
  if (d.id == s.next) {
    out.push_back(std::move(d));
    ++s.next;
    ++stats_.delivered;
    drain(s, out);
    return out;
  }
  s.ahead.emplace(d.id, std::move(d));
  ++stats_.held;
  if (s.ahead.size() > p_.max_held) {
    skip_gap(s, out);
  }
  return out;
}

std::vector<SyncWanted> DescriptorSequencer::wanted(Nanos now, const std::function<bool(uint32_t)>& reachable,
                                                    std::vector<DescriptorIn>& released) {
  std::vector<SyncWanted> out;
  for (auto& [robot, s] : streams_) {
    if (s.ahead.empty() || !reachable(robot)) continue;
    if (s.last_ask != Nanos::min() && now - s.last_ask < p_.resend) continue;
    if (s.last_ask != Nanos::min() && s.asked_for != s.next) {
      // The gap is being filled (an answer is still arriving): wait another interval rather than
      // ask again and have the same descriptors sent twice.
      s.asked_for = s.next;
      s.attempts = 0;
      s.last_ask = now;
      continue;
    }
    s.asked_for = s.next;
    if (s.attempts >= p_.max_attempts) {
      skip_gap(s, released);
      if (s.ahead.empty()) continue;
      s.asked_for = s.next;
    }
    out.push_back({robot, s.next, s.ahead.begin()->first - 1});
    s.last_ask = now;
    ++s.attempts;
    ++stats_.sync_requests;
  }
  return out;
}

uint32_t DescriptorSequencer::next_expected(uint32_t robot) const {
  const auto it = streams_.find(robot);
  return it == streams_.end() ? 0 : it->second.next;
}

size_t DescriptorSequencer::held(uint32_t robot) const {
  const auto it = streams_.find(robot);
  return it == streams_.end() ? 0 : it->second.ahead.size();
}

}  // namespace cdc::loops
