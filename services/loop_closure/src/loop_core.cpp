#include "cdc/loop_closure/loop_core.hpp"

#include <algorithm>

namespace cdc::loops {

void LoopEvents::append(LoopEvents&& o) {
  loops.insert(loops.end(), o.loops.begin(), o.loops.end());
  requests.insert(requests.end(), o.requests.begin(), o.requests.end());
  verifications.insert(verifications.end(), o.verifications.begin(), o.verifications.end());
}

lidar::ScanContext wire_form(const lidar::ScanContext& sc) { return lidar::dequantize(lidar::quantize(sc)); }

LoopCore::LoopCore(const LoopParams& params, std::optional<uint32_t> query_robot)
    : p_(params), query_robot_(query_robot), reachable_([](uint32_t) { return true; }), db_(params.scan_context.rings) {}

void LoopCore::add_odometry(uint32_t robot, uint32_t from, uint32_t to, const Eigen::Isometry3d& T,
                            const graph::Matrix6d& info) {
  odometry_.add_between(graph::make_key(robot, from), graph::make_key(robot, to), T, info);
}

LoopEvents LoopCore::add_keyframe_data(KeyframeIn kf, Nanos now) {
  const Id me{kf.robot, kf.id};
  if (local_.count(me) != 0) {
    return {};
  }
  if (kf.id > 0) {
    add_odometry(kf.robot, kf.id - 1u, kf.id, kf.T_prev, kf.information);
  }
  if (const auto prev = chained_.find({kf.robot, kf.id - 1u}); kf.id > 0 && prev != chained_.end()) {
    chained_[me] = {prev->second.pose * kf.T_prev, prev->second.path_m + kf.T_prev.translation().norm()};
  } else if (data_robots_.count(kf.robot) == 0) {
    chained_[me] = {Eigen::Isometry3d::Identity(), 0.0};
  }
  data_robots_.insert(kf.robot);
  up_[me] = kf.T_odom.linear().transpose() * Eigen::Vector3d::UnitZ();
  set_cloud(me, lidar::voxel_downsample(kf.cloud, p_.registration.voxel_m));
  local_.insert(me);
  auto it = deferred_.find(me);
  if (it == deferred_.end()) {
    return {};
  }
  DescriptorIn d = std::move(it->second);
  deferred_.erase(it);
  return add_descriptor(std::move(d), now);
}

LoopEvents LoopCore::add_descriptor(DescriptorIn d, Nanos now) {
  LoopEvents out;
  const Id me{d.robot, d.id};
  const bool query_robot = !query_robot_ || *query_robot_ == d.robot;
  if (query_robot && local_.count(me) == 0 && described_.count(me) == 0) {
    // Its keyframe (cloud, odometry) has not arrived yet: search when it does.
    if (deferred_.size() >= 64) {
      DescriptorIn oldest = std::move(deferred_.begin()->second);
      deferred_.erase(deferred_.begin());
      ++stats_.deferred_dropped;
      described_.insert({oldest.robot, oldest.id});
      db_.add(std::move(oldest.context));
      owner_.push_back({oldest.robot, oldest.id});
    }
    deferred_[me] = std::move(d);
    return out;
  }
  if (!described_.insert(me).second) {
    ++stats_.duplicate_descriptors;
    return out;
  }
  if (query_robot_ && d.robot != *query_robot_) {
    hints_[me] = d.pose_hint;
  }
  // Robots without local odometry are chained through their pose hints.
  if (data_robots_.count(d.robot) == 0) {
    auto it = last_hint_.find(d.robot);
    if (it != last_hint_.end() && it->second.first < d.id) {
      const Eigen::Isometry3d T = it->second.second.inverse() * d.pose_hint;
      const double len = T.translation().norm();
      const double st = p_.hint_sigma_m + p_.hint_sigma_m_per_m * len;
      const double sr = p_.hint_sigma_rad + p_.hint_sigma_rad_per_m * len;
      graph::Matrix6d info = graph::Matrix6d::Zero();
      info.diagonal() << 1 / (st * st), 1 / (st * st), 1 / (st * st), 1 / (sr * sr), 1 / (sr * sr), 1 / (sr * sr);
      add_odometry(d.robot, it->second.first, d.id, T, info);
    }
    if (it == last_hint_.end() || it->second.first < d.id) {
      last_hint_[d.robot] = {d.id, d.pose_hint};
    }
  }
  const bool searches = query_robot && local_.count(me) != 0;
  // A peer's descriptor (a robot's service only) is searched the other way round, among this
  // robot's own keyframes: peers' descriptors arrive in bursts when a peer comes back in range
  // (the history of everything it described meanwhile), and a peer's place this robot saw long
  // ago would otherwise only be found if this robot passed there again.
  const bool reverse = query_robot_ && d.robot != *query_robot_;
  std::vector<lidar::ScanContextDatabase::Candidate> candidates;
  if (searches) {
    ++stats_.queries;
    candidates = db_.query(d.context, p_.knn, [&](size_t id) {
      const auto& [robot, k] = owner_[id];
      if (robot != d.robot) return true;
      if (k + p_.exclude_recent >= d.id) return false;
      if (intra_plausible(me, owner_[id])) return true;
      ++stats_.intra_gated;
      return false;
    });
  } else if (reverse) {
    ++stats_.reverse_queries;
    candidates = db_.query(d.context, p_.knn, [&](size_t id) { return owner_[id].first == *query_robot_; });
  }
  db_.add(std::move(d.context));
  owner_.push_back(me);

  size_t taken = 0;
  for (const auto& c : candidates) {
    if (c.match.distance > p_.max_sc_distance || taken >= p_.max_verify) break;
    const uint32_t other = reverse ? d.robot : owner_[c.id].first;
    if (p_.lower_robot_verifies && query_robot_ && other < *query_robot_) {
      ++stats_.left_to_lower_robot;
      continue;
    }
    ++taken;
    ++stats_.candidates;
    // The job's query is always one of this robot's keyframes and its candidate the other one: for
    // a reverse search the roles swap, and so does the sign of the yaw between them.
    const double yaw = reverse ? -c.match.yaw_rad : c.match.yaw_rad;
    // The query is rotated by yaw relative to the candidate: T_candidate_query starts at Rz(-yaw).
    const Job job{reverse ? owner_[c.id] : me, reverse ? me : owner_[c.id],
                  Eigen::Isometry3d(Eigen::AngleAxisd(-yaw, Eigen::Vector3d::UnitZ()))};
    if (clouds_.count(job.candidate) != 0) {
      if (tried_.insert({job.query, job.candidate}).second) out.append(verify(job));
      continue;
    }
    bool too_far = false;
    if (const std::optional<Job> n = neighbour_job(job, too_far)) {
      // Several candidates of one query can share a neighbour: that pair is verified once.
      if (!tried_.insert({n->query, n->candidate}).second) continue;
      ++stats_.verified_with_neighbour;
      if (clouds_.count(n->candidate) != 0) {
        out.append(verify(*n));
      } else {
        wait_for_cloud(*n, now, out);
      }
      continue;
    }
    if (too_far) {
      ++stats_.reaim_too_far;
      continue;
    }
    if (tried_.count({job.query, job.candidate}) != 0) {
      continue;  // already waiting for this cloud
    }
    if (p_.peer_request_spacing > 0 && pending_.count(job.candidate) == 0) {
      std::set<uint32_t>& asked = requested_[job.candidate.first];
      const uint32_t id = job.candidate.second;
      const auto near = asked.lower_bound(id > p_.peer_request_spacing ? id - p_.peer_request_spacing : 0);
      if (near != asked.end() && *near <= id + p_.peer_request_spacing) {
        ++stats_.skipped_near_requested;
        continue;
      }
      asked.insert(id);
    }
    tried_.insert({job.query, job.candidate});
    wait_for_cloud(job, now, out);
  }
  return out;
}

void LoopCore::wait_for_cloud(const Job& job, Nanos now, LoopEvents& out) {
  for (std::map<Id, Pending>* waiting : {&pending_, &parked_}) {
    if (auto it = waiting->find(job.candidate); it != waiting->end()) {
      it->second.jobs.push_back(job);
      return;
    }
  }
  Pending p;
  p.jobs.push_back(job);
  if (!reachable_(job.candidate.first)) {
    // Its owner is out of range: the request waits, parked, until the owner is back in reach (tick
    // asks it then, with all its attempts still to come). Dropping it lost every loop with a place
    // a peer passed while out of range, unless the peer came back in range at that very moment.
    ++stats_.unreachable;
    p.attempts = 0;
    p.deadline = now;
    parked_.emplace(job.candidate, std::move(p));
    return;
  }
  p.deadline = now + p_.request_timeout;
  pending_.emplace(job.candidate, std::move(p));
  out.requests.push_back({job.candidate.first, job.candidate.second});
  ++stats_.requests;
}

bool LoopCore::intra_plausible(const Id& query, const Id& candidate) const {
  if (p_.intra_gate_m <= 0) return true;
  const auto q = chained_.find(query), c = chained_.find(candidate);
  if (q == chained_.end() || c == chained_.end()) return true;  // no unbroken chain between them: no evidence
  const double apart = (q->second.pose.translation() - c->second.pose.translation()).norm();
  return apart <= p_.intra_gate_m + p_.intra_gate_per_m * std::abs(q->second.path_m - c->second.path_m);
}

std::optional<LoopCore::Job> LoopCore::neighbour_job(const Job& job, bool& too_far) const {
  too_far = false;
  const auto [robot, id] = job.candidate;
  const auto asked = requested_.find(robot);
  const auto hint = hints_.find(job.candidate);
  if (p_.peer_request_spacing == 0 || asked == requested_.end() || hint == hints_.end()) {
    return std::nullopt;
  }
  const auto gap = [id = id](uint32_t other) { return other > id ? other - id : id - other; };
  std::optional<Job> best;
  uint32_t best_gap = 0;
  const auto consider = [&](std::set<uint32_t>::const_iterator it) {
    if (it == asked->second.end()) return;
    const Id n{robot, *it};
    const auto n_hint = hints_.find(n);
    if (gap(*it) == 0 || gap(*it) > p_.peer_request_spacing || n_hint == hints_.end()) return;
    if (clouds_.count(n) == 0 && pending_.count(n) == 0 && parked_.count(n) == 0) return;  // evicted or abandoned
    const Eigen::Isometry3d guess = n_hint->second.inverse() * hint->second * job.guess;
    if (p_.reaim_max_m > 0 && guess.translation().norm() > p_.reaim_max_m) {
      too_far = true;
      return;
    }
    if (!best || gap(*it) < best_gap) {
      best = Job{job.query, n, guess};
      best_gap = gap(*it);
    }
  };
  const auto above = asked->second.lower_bound(id);
  consider(above);
  if (above != asked->second.begin()) consider(std::prev(above));
  if (best) too_far = false;
  return best;
}

LoopEvents LoopCore::on_cloud(uint32_t robot, uint32_t id, std::vector<Eigen::Vector3f> cloud, Nanos) {
  LoopEvents out;
  const Id key{robot, id};
  // An answer to an earlier attempt of a request that was asked again, or is parked to be, counts too.
  std::map<Id, Pending>& from = pending_.count(key) != 0 ? pending_ : parked_;
  auto it = from.find(key);
  if (it == from.end()) {
    ++stats_.replies_unexpected;
    return out;
  }
  ++stats_.replies;
  const std::vector<Job> jobs = std::move(it->second.jobs);
  from.erase(it);
  if (local_.count(key) == 0) {
    set_cloud(key, lidar::voxel_downsample(cloud, p_.registration.voxel_m));
    cache_order_.push_back(key);
    while (cache_order_.size() > p_.cloud_cache) {
      clouds_.erase(cache_order_.front());
      drop_prepared(cache_order_.front());
      cache_order_.pop_front();
    }
  }
  for (const Job& j : jobs) {
    out.append(verify(j));
  }
  return out;
}

void LoopCore::park(const Id& candidate, Pending p, Nanos now) {
  if (p.attempts >= p_.request_attempts) {
    ++stats_.requests_abandoned;
    return;
  }
  p.deadline = now + p_.request_retry;
  parked_[candidate] = std::move(p);
}

void LoopCore::on_cloud_missing(uint32_t robot, uint32_t id, Nanos now) {
  auto it = pending_.find({robot, id});
  if (it == pending_.end()) {  // (a parked request stays parked)
    ++stats_.replies_unexpected;
    return;
  }
  ++stats_.missing;
  Pending p = std::move(it->second);
  pending_.erase(it);
  park({robot, id}, std::move(p), now);
}

LoopEvents LoopCore::tick(Nanos now) {
  LoopEvents out;
  for (auto it = pending_.begin(); it != pending_.end();) {
    if (it->second.deadline <= now) {
      ++stats_.timed_out;
      park(it->first, std::move(it->second), now);
      it = pending_.erase(it);
    } else {
      ++it;
    }
  }
  for (auto it = parked_.begin(); it != parked_.end();) {
    if (it->second.deadline > now || !reachable_(it->first.first)) {
      ++it;
      continue;
    }
    Pending p = std::move(it->second);
    ++p.attempts;
    p.deadline = now + p_.request_timeout;
    out.requests.push_back({it->first.first, it->first.second});
    ++stats_.requests;
    ++stats_.requests_retried;
    pending_[it->first] = std::move(p);
    it = parked_.erase(it);
  }
  return out;
}

std::vector<LoopOut> LoopCore::add_keyframe(KeyframeIn kf) {
  DescriptorIn d;
  d.robot = kf.robot;
  d.id = kf.id;
  d.context = wire_form(lidar::make_scan_context(kf.cloud, p_.scan_context));
  add_keyframe_data(std::move(kf), Nanos(0));
  return add_descriptor(std::move(d), Nanos(0)).loops;
}

const std::vector<Eigen::Vector3f>* LoopCore::cloud(uint32_t robot, uint32_t id) const {
  auto it = clouds_.find({robot, id});
  return it == clouds_.end() ? nullptr : &it->second;
}

void LoopCore::set_cloud(const Id& id, std::vector<Eigen::Vector3f> cloud) {
  clouds_[id] = std::move(cloud);
  drop_prepared(id);
}

void LoopCore::drop_prepared(const Id& id) {
  prepared_.erase(std::remove_if(prepared_.begin(), prepared_.end(), [&](const auto& e) { return e.first == id; }),
                  prepared_.end());
}

std::shared_ptr<const lidar::PreparedCloud> LoopCore::prepared(const Id& id, const std::vector<Eigen::Vector3f>& cloud) {
  const auto it = std::find_if(prepared_.begin(), prepared_.end(), [&](const auto& e) { return e.first == id; });
  if (it != prepared_.end()) {
    ++stats_.prepared_reused;
    auto entry = *it;
    prepared_.erase(it);
    prepared_.push_front(entry);
    return entry.second;
  }
  lidar::RegistrationParams rp = p_.registration;
  rp.voxel_m = 0;  // the held clouds are downsampled already
  auto ready = std::make_shared<const lidar::PreparedCloud>(cloud, rp);
  ++stats_.prepared;
  if (p_.prepared_clouds > 0) {
    prepared_.emplace_front(id, ready);
    while (prepared_.size() > p_.prepared_clouds) prepared_.pop_back();
  }
  return ready;
}

LoopEvents LoopCore::verify(const Job& job) {
  LoopEvents out;
  const auto src = clouds_.find(job.query), tgt = clouds_.find(job.candidate);
  if (src == clouds_.end() || tgt == clouds_.end()) {
    return out;
  }
  const auto [robot_a, kf_a] = job.candidate;
  const auto [robot_b, kf_b] = job.query;
  const lidar::RegistrationResult r =
      lidar::register_clouds(*prepared(job.query, src->second), *prepared(job.candidate, tgt->second), job.guess, p_.registration);
  ++stats_.verified;
  Verification v{robot_b, kf_b, robot_a, kf_a, r.converged, false, r.fitness, r.overlap,
                 job.guess.translation().norm(), (job.guess.inverse() * r.T_target_source).translation().norm()};
  if (!r.converged || r.fitness > p_.max_fitness || r.overlap < p_.min_overlap) {
    ++stats_.verification_failed;
    ++(!r.converged ? stats_.failed_not_converged : r.fitness > p_.max_fitness ? stats_.failed_fitness : stats_.failed_overlap);
    out.verifications.push_back(v);
    return out;
  }
  v.passed = true;
  out.verifications.push_back(v);
  // The residual's rotation is taken in the query keyframe's frame (b): level it there.
  const auto up = up_.find(job.query);
  const graph::Matrix6d information =
      graph::level_information(p_.loop_information_scale * r.information, up == up_.end() ? Eigen::Vector3d::UnitZ() : up->second,
                               p_.tilt_information_scale);
  LoopOut loop{robot_a, kf_a, robot_b, kf_b, r.T_target_source, information, r.fitness, false};
  graph::Factor f;
  f.kind = graph::FactorKind::kLoop;
  f.a = graph::make_key(robot_a, kf_a);
  f.b = graph::make_key(robot_b, kf_b);
  f.measurement = loop.T_a_b;
  f.information = loop.information;
  if (robot_a == robot_b) {
    // An intra-robot loop must agree with the robot's own odometry between the two keyframes.
    if (graph::Pcm::odometry_distance(odometry_, f) > p_.pcm.chi2_threshold) {
      ++stats_.intra_inconsistent;
      return out;
    }
    ++stats_.intra_accepted;
    odometry_.add_between(f.a, f.b, loop.T_a_b, loop.information);
    out.loops.push_back(loop);
    return out;
  }
  ++stats_.inter_proposed;
  odometry_.add_between(f.a, f.b, loop.T_a_b, loop.information);
  const size_t id = odometry_.factors.size() - 1;
  inter_[{std::min(robot_a, robot_b), std::max(robot_a, robot_b)}].push_back(id);
  proposed_[id] = loop;
  out.append(update_pcm(std::min(robot_a, robot_b), std::max(robot_a, robot_b)));
  return out;
}

LoopEvents LoopCore::update_pcm(uint32_t a, uint32_t b) {
  LoopEvents out;
  // PCM over this pair only: both robots' odometry and the pair's proposed loops.
  graph::PoseGraph g;
  const std::vector<size_t>& ids = inter_[{a, b}];
  for (const graph::Factor& f : odometry_.factors) {
    if (f.kind == graph::FactorKind::kOdometry && (graph::robot_of(f.a) == a || graph::robot_of(f.a) == b)) {
      g.factors.push_back(f);
    }
  }
  const size_t first_loop = g.factors.size();
  for (size_t f : ids) {
    g.factors.push_back(odometry_.factors[f]);
  }
  const graph::OutlierDecision d = graph::Pcm(p_.pcm).decide(g);
  // The consistent set is published when it is large enough and rests on more than one keyframe of
  // each robot: loops sharing a keyframe share its cloud, and a registration that slid along a
  // featureless stretch slides the same way for all of them (consistent, and wrong together).
  std::set<uint32_t> keyframes_a, keyframes_b;
  for (size_t i : d.accepted) {
    const LoopOut& l = proposed_.at(ids[i - first_loop]);
    keyframes_a.insert(l.robot_a == a ? l.keyframe_a : l.keyframe_b);
    keyframes_b.insert(l.robot_a == a ? l.keyframe_b : l.keyframe_a);
  }
  const size_t distinct = std::min<size_t>(2, p_.min_inter_support);
  std::set<size_t> accepted;
  if (d.accepted.size() >= p_.min_inter_support && keyframes_a.size() >= distinct && keyframes_b.size() >= distinct) {
    for (size_t i : d.accepted) accepted.insert(ids[i - first_loop]);
  }
  for (size_t f : ids) {
    const bool now = accepted.count(f) != 0, before = published_.count(f) != 0;
    if (now && !before) {
      published_.insert(f);
      ++stats_.inter_accepted;
      out.loops.push_back(proposed_[f]);
    } else if (!now && before) {
      published_.erase(f);
      ++stats_.withdrawn;
      LoopOut w = proposed_[f];
      w.withdrawn = true;
      out.loops.push_back(w);
    }
  }
  return out;
}

}  // namespace cdc::loops
