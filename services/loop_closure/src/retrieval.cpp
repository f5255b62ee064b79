#include "cdc/loop_closure/retrieval.hpp"

#include <cmath>
#include <utility>

namespace cdc::loops {

void IntraGate::add(uint32_t robot, uint32_t id, const Eigen::Isometry3d& T_prev) {
  if (const auto prev = chained_.find({robot, id - 1u}); id > 0 && prev != chained_.end()) {
    chained_[{robot, id}] = {prev->second.pose * T_prev, prev->second.path_m + T_prev.translation().norm()};
  } else if (started_.count(robot) == 0) {
    chained_[{robot, id}] = {Eigen::Isometry3d::Identity(), 0.0};
  }
  started_.insert(robot);
}

bool IntraGate::plausible(const KeyframeId& query, const KeyframeId& candidate) const {
  if (gate_m_ <= 0) return true;
  const auto q = chained_.find(query), c = chained_.find(candidate);
  if (q == chained_.end() || c == chained_.end()) return true;  // no unbroken chain between them: no evidence
  const double apart = (q->second.pose.translation() - c->second.pose.translation()).norm();
  return apart <= gate_m_ + gate_per_m_ * std::abs(q->second.path_m - c->second.path_m);
}

Retrieval::Retrieval(const LoopParams& params, std::optional<uint32_t> query_robot)
    : p_(params),
      query_robot_(query_robot),
      gate_(params.intra_gate_m, params.intra_gate_per_m),
      db_(params.scan_context.rings) {}

bool Retrieval::waits_for_keyframe(const DescriptorIn& d, bool keyframe_held) const {
  return is_query_robot(d.robot) && !keyframe_held && described_.count({d.robot, d.id}) == 0;
}

void Retrieval::defer(DescriptorIn d) {
  if (deferred_.size() >= kMaxDeferred) {
    DescriptorIn oldest = std::move(deferred_.begin()->second);
    deferred_.erase(deferred_.begin());
    ++stats_.deferred_dropped;
    described_.insert({oldest.robot, oldest.id});
    add_to_database({oldest.robot, oldest.id}, std::move(oldest.context));
  }
  const KeyframeId id{d.robot, d.id};
  deferred_[id] = std::move(d);
}

std::optional<DescriptorIn> Retrieval::take_deferred(const KeyframeId& id) {
  auto it = deferred_.find(id);
  if (it == deferred_.end()) return std::nullopt;
  DescriptorIn d = std::move(it->second);
  deferred_.erase(it);
  return d;
}

bool Retrieval::first_description(const KeyframeId& id) {
  if (described_.insert(id).second) return true;
  ++stats_.duplicate_descriptors;
  return false;
}

void Retrieval::add_views(const KeyframeId& id, std::vector<ShiftedView> views) {
  if (!views.empty()) views_[id] = std::move(views);
}

std::vector<VerificationJob> Retrieval::search(DescriptorIn d, bool keyframe_held) {
  const KeyframeId me{d.robot, d.id};
  const bool reverse = is_peer(d.robot);
  std::vector<Match> matches;
  if (is_query_robot(d.robot) && keyframe_held) {
    matches = search_forward(d);
  } else if (reverse) {
    matches = search_reverse(d);
  }
  add_to_database(me, std::move(d.context));
  if (auto v = views_.find(me); v != views_.end()) {
    for (ShiftedView& view : v->second) add_to_database(me, std::move(view.context), view.sensor);
    views_.erase(v);
  }
  return take_candidates(best_per_keyframe(std::move(matches)), me, reverse);
}

// The descriptor among every keyframe's (and views beside them); the keyframe's own views among
// keyframes' descriptors (a view matched with a view would be two lanes aside, or none).
std::vector<Retrieval::Match> Retrieval::search_forward(const DescriptorIn& d) {
  ++stats_.queries;
  const auto allowed = [&](size_t id) {
    const auto& [robot, k] = owner_[id];
    if (robot != d.robot) return true;
    if (k + p_.exclude_recent >= d.id) return false;
    if (gate_.plausible({d.robot, d.id}, owner_[id])) return true;
    ++stats_.intra_gated;
    return false;
  };
  std::vector<Match> out;
  for (const auto& c : db_.query(d.context, p_.knn, allowed)) out.push_back({c, Eigen::Vector3d::Zero()});
  const auto views = views_.find({d.robot, d.id});
  if (views == views_.end()) return out;
  for (const ShiftedView& v : views->second) {
    const auto original = [&](size_t id) { return sensor_[id].isZero() && allowed(id); };
    for (const auto& c : db_.query(v.context, p_.knn, original)) out.push_back({c, v.sensor});
  }
  return out;
}

// Peers' descriptors arrive in bursts when a peer comes back in range (the history of everything it
// described meanwhile): a peer's place this robot saw long ago would otherwise only be found if this
// robot passed there again.
std::vector<Retrieval::Match> Retrieval::search_reverse(const DescriptorIn& d) {
  ++stats_.reverse_queries;
  std::vector<Match> out;
  for (const auto& c : db_.query(d.context, p_.knn, [&](size_t id) { return owner_[id].first == *query_robot_; })) {
    out.push_back({c, Eigen::Vector3d::Zero()});
  }
  return out;
}

std::vector<Retrieval::Match> Retrieval::best_per_keyframe(std::vector<Match> matches) const {
  std::stable_sort(matches.begin(), matches.end(),
                   [](const Match& a, const Match& b) { return a.found.match.distance < b.found.match.distance; });
  std::vector<Match> out;
  std::set<KeyframeId> seen;
  for (const Match& m : matches) {
    if (seen.insert(owner_[m.found.id]).second) out.push_back(m);
  }
  return out;
}

void Retrieval::add_to_database(const KeyframeId& id, lidar::ScanContext context, const Eigen::Vector3d& sensor) {
  db_.add(std::move(context));
  owner_.push_back(id);
  sensor_.push_back(sensor);
}

std::vector<VerificationJob> Retrieval::take_candidates(const std::vector<Match>& matches, const KeyframeId& me,
                                                        bool reverse) {
  std::vector<VerificationJob> jobs;
  for (const Match& m : matches) {
    const lidar::ScanContextDatabase::Candidate& c = m.found;
    if (c.match.distance > p_.max_sc_distance || jobs.size() >= p_.max_verify) break;
    const uint32_t other = reverse ? me.first : owner_[c.id].first;
    if (p_.lower_robot_verifies && query_robot_ && other < *query_robot_) {
      ++stats_.left_to_lower_robot;
      continue;
    }
    ++stats_.candidates;
    // The searched descriptor is rotated by yaw relative to the database's: the database entry's
    // sensor sees the searched one at Rz(-yaw), each sensor where its keyframe's view put it.
    const Eigen::Isometry3d T_entry_searched = Eigen::Translation3d(sensor_[c.id]) *
                                               Eigen::AngleAxisd(-c.match.yaw_rad, Eigen::Vector3d::UnitZ()) *
                                               Eigen::Translation3d(-m.searched_from);
    // The job's query is always one of this robot's keyframes and its candidate the other one: for
    // a reverse search the roles swap. Its guess is T_candidate_query.
    jobs.push_back({reverse ? owner_[c.id] : me, reverse ? me : owner_[c.id],
                    reverse ? T_entry_searched.inverse() : T_entry_searched});
  }
  return jobs;
}

}  // namespace cdc::loops
