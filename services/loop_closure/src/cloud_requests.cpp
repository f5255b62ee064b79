#include "cdc/loop_closure/cloud_requests.hpp"

#include <iterator>
#include <utility>

namespace cdc::loops {

CloudRequests::CloudRequests(const LoopParams& params) : p_(params), reachable_([](uint32_t) { return true; }) {}

CloudRequests::Reaimed CloudRequests::reaim(const VerificationJob& job,
                                            const std::function<bool(const KeyframeId&)>& held) const {
  Reaimed out;
  const auto [robot, id] = job.candidate;
  const auto asked = requested_.find(robot);
  const auto hint = hints_.find(job.candidate);
  if (p_.peer_request_spacing == 0 || asked == requested_.end() || hint == hints_.end()) {
    return out;
  }
  const auto gap = [id = id](uint32_t other) { return other > id ? other - id : id - other; };
  uint32_t best_gap = 0;
  const auto consider = [&](std::set<uint32_t>::const_iterator it) {
    if (it == asked->second.end()) return;
    const KeyframeId n{robot, *it};
    const auto n_hint = hints_.find(n);
    if (gap(*it) == 0 || gap(*it) > p_.peer_request_spacing || n_hint == hints_.end()) return;
    if (!held(n) && !wanted(n)) return;  // evicted or abandoned
    const Eigen::Isometry3d guess = n_hint->second.inverse() * hint->second * job.guess;
    if (p_.reaim_max_m > 0 && guess.translation().norm() > p_.reaim_max_m) {
      out.too_far = true;
      return;
    }
    if (!out.job || gap(*it) < best_gap) {
      out.job = VerificationJob{job.query, n, guess};
      best_gap = gap(*it);
    }
  };
  const auto above = asked->second.lower_bound(id);
  consider(above);
  if (above != asked->second.begin()) consider(std::prev(above));
  if (out.job) out.too_far = false;
  return out;
}

bool CloudRequests::reserve(const KeyframeId& candidate) {
  if (p_.peer_request_spacing == 0 || pending_.count(candidate) != 0) return true;
  std::set<uint32_t>& asked = requested_[candidate.first];
  const uint32_t id = candidate.second;
  const auto near = asked.lower_bound(id > p_.peer_request_spacing ? id - p_.peer_request_spacing : 0);
  if (near != asked.end() && *near <= id + p_.peer_request_spacing) {
    ++stats_.skipped_near_requested;
    return false;
  }
  asked.insert(id);
  return true;
}

void CloudRequests::wait_for(const VerificationJob& job, Nanos now, std::vector<CloudWanted>& asked) {
  for (std::map<KeyframeId, Request>* waiting : {&pending_, &parked_}) {
    if (auto it = waiting->find(job.candidate); it != waiting->end()) {
      it->second.jobs.push_back(job);
      return;
    }
  }
  Request r;
  r.jobs.push_back(job);
  if (!reachable_(job.candidate.first)) {
    // Its owner is out of range: the request waits, parked, until the owner is back in reach (tick
    // asks it then, with all its attempts still to come), so that the places a peer passes while
    // out of range still close loops.
    ++stats_.unreachable;
    r.attempts = 0;
    r.deadline = now;
    parked_.emplace(job.candidate, std::move(r));
    return;
  }
  r.deadline = now + p_.request_timeout;
  pending_.emplace(job.candidate, std::move(r));
  asked.push_back({job.candidate.first, job.candidate.second});
  ++stats_.requests;
}

std::optional<std::vector<VerificationJob>> CloudRequests::answered(const KeyframeId& id) {
  // An answer to an earlier attempt of a request that was asked again, or is parked to be, counts too.
  std::map<KeyframeId, Request>& from = pending_.count(id) != 0 ? pending_ : parked_;
  auto it = from.find(id);
  if (it == from.end()) {
    ++stats_.replies_unexpected;
    return std::nullopt;
  }
  ++stats_.replies;
  std::vector<VerificationJob> jobs = std::move(it->second.jobs);
  from.erase(it);
  return jobs;
}

void CloudRequests::park(const KeyframeId& id, Request r, Nanos now) {
  if (r.attempts >= p_.request_attempts) {
    ++stats_.requests_abandoned;
    return;
  }
  r.deadline = now + p_.request_retry;
  parked_[id] = std::move(r);
}

void CloudRequests::missing(const KeyframeId& id, Nanos now) {
  auto it = pending_.find(id);
  if (it == pending_.end()) {
    ++stats_.replies_unexpected;
    return;
  }
  ++stats_.missing;
  Request r = std::move(it->second);
  pending_.erase(it);
  park(id, std::move(r), now);
}

std::vector<CloudWanted> CloudRequests::tick(Nanos now) {
  std::vector<CloudWanted> asked;
  expire(now);
  ask_parked(now, asked);
  return asked;
}

void CloudRequests::expire(Nanos now) {
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (it->second.deadline <= now) {
      ++stats_.timed_out;
      park(it->first, std::move(it->second), now);
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
}

void CloudRequests::ask_parked(Nanos now, std::vector<CloudWanted>& asked) {
  for (auto it = parked_.begin(); it != parked_.end();) {
    if (it->second.deadline > now || !reachable_(it->first.first)) {
      ++it;
      continue;
    }
    Request r = std::move(it->second);
    ++r.attempts;
    r.deadline = now + p_.request_timeout;
    asked.push_back({it->first.first, it->first.second});
    ++stats_.requests;
    ++stats_.requests_retried;
    pending_[it->first] = std::move(r);
    it = parked_.erase(it);
  }
}

}  // namespace cdc::loops
