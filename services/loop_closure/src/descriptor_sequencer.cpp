#include "cdc/loop_closure/descriptor_sequencer.hpp"

#include <algorithm>

namespace cdc::loops {

void DescriptorSequencer::drain(Stream& s, std::vector<DescriptorIn>& out) {
  for (auto it = s.ahead.begin(); it != s.ahead.end() && it->first == s.next; it = s.ahead.erase(it)) {
    out.push_back(std::move(it->second));
    ++s.next;
    ++stats_.delivered;
  }
}

void DescriptorSequencer::skip_gap(Stream& s, std::vector<DescriptorIn>& out) {
  uint32_t to = 0;
  if (!s.ahead.empty()) {
    to = s.ahead.begin()->first;
  } else if (s.announced >= static_cast<int64_t>(s.next)) {
    to = static_cast<uint32_t>(s.announced) + 1;  // a tail that never came
  } else {
    return;
  }
  ++stats_.gaps_skipped;
  stats_.ids_skipped += to - s.next;
  s.next = to;
  s.attempts = 0;
  drain(s, out);
}

int64_t DescriptorSequencer::gap_end(const Stream& s, Nanos now) const {
  if (!s.ahead.empty()) return static_cast<int64_t>(s.ahead.begin()->first) - 1;
  // A tail: only once the owner's mark has stood for `resend`, so that live descriptors in flight
  // (the status can overtake them) are not asked for.
  if (s.announced >= static_cast<int64_t>(s.next) && now - s.announced_at >= p_.resend) return s.announced;
  return -1;
}

void DescriptorSequencer::announce(uint32_t robot, uint32_t last, Nanos now) {
  Stream& s = streams_[robot];
  if (static_cast<int64_t>(last) > s.announced) {
    s.announced = last;
    s.announced_at = now;
  }
}

uint64_t DescriptorSequencer::missing() const {
  uint64_t n = 0;
  for (const auto& [robot, s] : streams_) {
    int64_t last = s.announced;
    if (!s.ahead.empty()) last = std::max<int64_t>(last, s.ahead.rbegin()->first);
    if (last >= static_cast<int64_t>(s.next)) n += static_cast<uint64_t>(last + 1 - static_cast<int64_t>(s.next));
  }
  return n;
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
    if (gap_end(s, now) < 0 || !reachable(robot)) continue;
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
      if (gap_end(s, now) < 0) continue;
      s.asked_for = s.next;
    }
    out.push_back({robot, s.next, static_cast<uint32_t>(gap_end(s, now))});
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
