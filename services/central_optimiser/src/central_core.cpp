#include "cdc/central_optimiser/central_core.hpp"

#include "cdc/geometry/alignment.hpp"
#include "cdc/graph/objective.hpp"

#include <algorithm>
#include <chrono>

namespace cdc::central {
namespace {

constexpr double kAnchorInformation = 1e8;
// A local pass that does not converge carries its touched keys to the next; beyond this many windows'
// worth, a full pass takes them instead (the carried set would otherwise grow with every short pass).
constexpr size_t kMaxCarriedTouched = 4;
// Loops from an active key to keys held fixed that a local pass takes, per key (local_factors).
constexpr size_t kMaxAnchorsPerKey = 4;

}  // namespace

CentralCore::CentralCore(const CentralConfig& config) : config_(config), gnc_threshold_(config.loop_gnc_threshold) {}

CentralCore::Session* CentralCore::session(uint32_t robot, uint32_t incarnation, bool create) {
  auto& list = sessions_[robot];
  for (Session& s : list) {
    if (s.incarnation == incarnation) {
      return &s;
    }
  }
  if (!create) {
    return nullptr;
  }
  Session s;
  s.robot = robot;
  s.incarnation = incarnation;
  s.index = static_cast<uint32_t>(list.size());
  list.push_back(std::move(s));
  return &list.back();
}

CentralCore::Session* CentralCore::current_session(uint32_t robot) {
  auto it = sessions_.find(robot);
  if (it == sessions_.end() || it->second.empty()) {
    return nullptr;
  }
  return &it->second.back();
}

AddResult CentralCore::add_keyframe(const KeyframeIn& kf) {
  if (kf.robot >= config_.robot_count) {
    ++counters_.keyframes_rejected;
    return {Outcome::kRejected, "unknown robot id " + std::to_string(kf.robot)};
  }
  Session* s = session(kf.robot, kf.incarnation, true);
  if (const auto held = s->keyframes.find(kf.id); held != s->keyframes.end()) {
    return held_already(held->second, kf);
  }
  if (kf.id > s->contiguous && pending_keyframes_ >= config_.max_pending_keyframes) {
    ++counters_.keyframes_rejected;
    ++counters_.keyframes_pending_full;
    return {Outcome::kRejected, "keyframe " + std::to_string(kf.id) + " of robot " + std::to_string(kf.robot) +
                                    " waits for keyframe " + std::to_string(s->contiguous) + " and " +
                                    std::to_string(pending_keyframes_) +
                                    " keyframes already wait (max_pending_keyframes)"};
  }
  hold(*s, kf);
  ++counters_.keyframes_accepted;
  // The world frame is robot 0's first odometry frame: its first keyframe anchors the graph.
  const bool anchor = kf.robot == 0 && s->index == 0 && kf.id == 0;
  if (anchor && !s->placed) {
    graph_.add_prior(key(*s, 0), kf.T_odom_keyframe, Matrix6d::Identity() * kAnchorInformation);
    factors_at_[key(*s, 0)].push_back(graph_.factors.size() - 1);
    graph_.poses[key(*s, 0)] = kf.T_odom_keyframe;
    s->in_graph = 1;
    s->keyframes.at(0).link.reset();
    s->placed = true;
    s->T_world_odom = Eigen::Isometry3d::Identity();
  }
  if (s->placed) {
    insert_ready_keyframes(*s);
  }
  if (!pending_loops_.empty()) try_insert_loops();
  dirty_ = true;
  return {};
}

// A keyframe id names one keyframe of a robot's sequence (idl/README.md): the same keyframe again (a
// re-send) is a duplicate; other contents under a held id (a front-end that numbered afresh under the
// same incarnation) are refused, never taken for a duplicate.
AddResult CentralCore::held_already(const Held& held, const KeyframeIn& kf) {
  if (held.stamp_ns == kf.stamp_ns) {
    ++counters_.keyframes_duplicate;
    return {Outcome::kDuplicate, {}};
  }
  ++counters_.keyframes_rejected;
  return {Outcome::kRejected, "robot " + std::to_string(kf.robot) + " keyframe " + std::to_string(kf.id) +
                                  " of incarnation " + std::to_string(kf.incarnation) + " (stamp " +
                                  std::to_string(kf.stamp_ns) + " ns): id held already with stamp " +
                                  std::to_string(held.stamp_ns) + " ns (other contents)"};
}

// Holds kf and moves the session's contiguous end past every keyframe that now follows without a
// gap: those stop pending. Each keyframe is passed over once, so the intake costs O(log n) each.
void CentralCore::hold(Session& s, const KeyframeIn& kf) {
  Held h{kf.stamp_ns, kf.T_odom_keyframe, std::make_unique<Held::Link>(Held::Link{kf.T_prev_keyframe, kf.information})};
  auto it = s.keyframes.emplace(kf.id, std::move(h)).first;
  if (kf.id != s.contiguous) {
    ++pending_keyframes_;
    return;
  }
  ++s.contiguous;
  for (++it; it != s.keyframes.end() && it->first == s.contiguous; ++it) {
    ++s.contiguous;
    --pending_keyframes_;
  }
}

// Chains the held keyframes that follow the graph's newest one of the session, in id order: the
// graph holds ids 0 .. in_graph - 1, so the next one is looked up, never searched for.
void CentralCore::insert_ready_keyframes(Session& s) {
  for (uint64_t next = s.in_graph; next < s.contiguous; ++next) {
    const auto id = static_cast<uint32_t>(next);
    Held& kf = s.keyframes.at(id);
    const std::unique_ptr<Held::Link> link = std::move(kf.link);
    s.in_graph = id + 1;
    touch(s, id);
    if (id == 0) {
      graph_.poses[key(s, 0)] = s.T_world_odom * kf.T_odom_keyframe;
      continue;
    }
    const Key prev = key(s, id - 1), cur = key(s, id);
    graph_.poses[cur] = graph_.poses.at(prev) * link->T_prev_keyframe;  // chained from the optimised predecessor
    add_between(prev, cur, link->T_prev_keyframe, link->information);
    // A backlog (a robot's re-sent keyframes after a rejoin, with the loops it missed) is more than a
    // window: a local pass holds the rest of that robot fixed, and the loops that should turn its whole
    // trajectory bend only its end. Robot 2 of the demo: its fitted T_world_robot 0.2 m and 3 mrad off
    // for 2 s of local passes, then a full pass moved its corrected newest keyframe 0.15-0.3 m.
    // In a long mission a robot gains `window` keyframes every few seconds: the bound grows with the
    // session, so that steady growth pays for its full passes and a backlog still triggers one.
    const double grown = std::max<double>(config_.window, config_.full_growth * static_cast<double>(s.in_graph));
    if (++s.inserted_since_full > grown) need_full_ = true;
  }
}

void CentralCore::place(Session& s, const Eigen::Isometry3d& T_world_odom) {
  need_full_ = true;
  s.placed = true;
  s.T_world_odom = T_world_odom;
  insert_ready_keyframes(s);
}

// Tries the loops waiting for their keyframes (only those: a loop in the graph is never looked at
// again), until none can go in; a loop that places a session may let earlier ones in.
void CentralCore::try_insert_loops() {
  bool progress = true;
  while (progress) {
    progress = false;
    for (size_t index : pending_loops_) {
      StoredLoop& l = loops_[index];
      if (l.in_graph || l.in.withdrawn) {
        continue;
      }
      Session* sa = current_session(l.in.robot_a);
      Session* sb = current_session(l.in.robot_b);
      if (sa == nullptr || sb == nullptr || sa->keyframes.count(l.in.keyframe_a) == 0 ||
          sb->keyframes.count(l.in.keyframe_b) == 0) {
        continue;
      }
      // Place a session the first time a loop ties it to the anchored graph.
      if (sa->placed && !sb->placed && sa->has(l.in.keyframe_a)) {
        const Eigen::Isometry3d T_world_b = graph_.poses.at(key(*sa, l.in.keyframe_a)) * l.in.T_a_b;
        place(*sb, sb->hint.value_or(T_world_b * sb->keyframes.at(l.in.keyframe_b).T_odom_keyframe.inverse()));
        progress = true;
      } else if (sb->placed && !sa->placed && sb->has(l.in.keyframe_b)) {
        const Eigen::Isometry3d T_world_a = graph_.poses.at(key(*sb, l.in.keyframe_b)) * l.in.T_a_b.inverse();
        place(*sa, sa->hint.value_or(T_world_a * sa->keyframes.at(l.in.keyframe_a).T_odom_keyframe.inverse()));
        progress = true;
      }
      if (sa->has(l.in.keyframe_a) && sb->has(l.in.keyframe_b)) {
        add_between(key(*sa, l.in.keyframe_a), key(*sb, l.in.keyframe_b), l.in.T_a_b, l.in.information);
        l.in_graph = true;
        l.factor_index = graph_.factors.size() - 1;
        touch(*sa, l.in.keyframe_a);
        touch(*sb, l.in.keyframe_b);
        progress = true;
        dirty_ = true;
      }
    }
    std::erase_if(pending_loops_, [this](size_t i) { return loops_[i].in_graph || loops_[i].in.withdrawn; });
  }
}

// Every factor goes in through here: the key -> factor index and the loop counts follow the graph.
void CentralCore::add_between(Key a, Key b, const Eigen::Isometry3d& T_a_b, const Matrix6d& information) {
  graph_.add_between(a, b, T_a_b, information);
  const size_t i = graph_.factors.size() - 1;
  factors_at_[a].push_back(i);
  factors_at_[b].push_back(i);
  if (graph_.factors[i].kind == graph::FactorKind::kLoop) {
    ++loop_counts_[a];
    ++loop_counts_[b];
  }
  ++changes_since_full_;
}

void CentralCore::index_factors() {
  factors_at_.clear();
  for (size_t i = 0; i < graph_.factors.size(); ++i) {
    const graph::Factor& f = graph_.factors[i];
    factors_at_[f.a].push_back(i);
    if (f.b != f.a) factors_at_[f.b].push_back(i);
  }
  loop_counts_ = graph::loop_counts(graph_);
}

// A withdrawn loop leaves the graph (factor indices after it shift down; withdrawals are rare).
void CentralCore::withdraw(StoredLoop& l) {
  if (l.in_graph) {
    graph_.factors.erase(graph_.factors.begin() + static_cast<std::ptrdiff_t>(l.factor_index));
    if (l.factor_index < outliers_.size()) {
      if (outliers_[l.factor_index] != 0) --counters_.loops_outliers;
      outliers_.erase(outliers_.begin() + static_cast<std::ptrdiff_t>(l.factor_index));
      retries_.erase(retries_.begin() + static_cast<std::ptrdiff_t>(l.factor_index));
    }
    for (StoredLoop& other : loops_) {
      if (other.in_graph && other.factor_index > l.factor_index) {
        --other.factor_index;
      }
    }
    index_factors();
  }
  l.in.withdrawn = true;
  l.in_graph = false;
  ++counters_.loops_withdrawn;
  dirty_ = true;
}

// The sender's loop sequence numbers held, with the contiguous end moved past each one that closes a gap.
void CentralCore::hold_loop_seq(uint32_t sender, uint32_t incarnation, uint32_t seq) {
  Session& s = *session(sender, incarnation, true);
  s.loop_seqs.insert(seq);
  while (s.loop_seqs.count(static_cast<uint32_t>(s.loop_contiguous + 1)) != 0) ++s.loop_contiguous;
}

AddResult CentralCore::add_loop(const LoopIn& loop) {
  for (uint32_t r : {loop.sender, loop.robot_a, loop.robot_b}) {
    if (r >= config_.robot_count) {
      ++counters_.loops_rejected;
      return {Outcome::kRejected, "unknown robot id " + std::to_string(r)};
    }
  }
  if (loop.withdrawn) {
    for (StoredLoop& l : loops_) {
      if (!l.in.withdrawn && l.in.robot_a == loop.robot_a && l.in.keyframe_a == loop.keyframe_a &&
          l.in.robot_b == loop.robot_b && l.in.keyframe_b == loop.keyframe_b) {
        withdraw(l);
      }
    }
    hold_loop_seq(loop.sender, loop.sender_incarnation, loop.seq);
    return {};
  }
  const auto id = std::make_tuple(loop.sender, loop.sender_incarnation, loop.seq);
  if (loop_ids_.count(id) != 0) {
    ++counters_.loops_duplicate;
    return {Outcome::kDuplicate, {}};
  }
  // Refused, not held: the loop is not acknowledged, so its sender sends it again later.
  if (pending_loops_.size() >= config_.max_pending_loops) {
    ++counters_.loops_rejected;
    return {Outcome::kRejected,
            std::to_string(pending_loops_.size()) + " loops already wait for their keyframes (max_pending_loops)"};
  }
  loop_ids_.insert(id);
  hold_loop_seq(loop.sender, loop.sender_incarnation, loop.seq);
  pending_loops_.push_back(loops_.size());
  loops_.push_back({loop, false, 0});
  ++counters_.loops_accepted;
  try_insert_loops();
  dirty_ = true;
  return {};
}

void CentralCore::add_world_hint(uint32_t robot, uint32_t incarnation, const Eigen::Isometry3d& T_world_robot) {
  if (robot >= config_.robot_count) {
    return;
  }
  session(robot, incarnation, true)->hint = T_world_robot;
}

// The graph a full pass solves: a copy of the factors (less the loops held out as outliers, with the
// loops' information shared when so configured; ids[j] is pass factor j's index in graph_) and the
// poses themselves (moved, not copied: a long mission's pose nodes stay where they are in the heap
// instead of being reallocated among the pass's transient buffers every time).
graph::PoseGraph CentralCore::take_pass_graph(std::vector<size_t>& ids) {
  graph::PoseGraph pass;
  pass.dimension = graph_.dimension;
  pass.symbol_keys = graph_.symbol_keys;
  pass.factors.reserve(graph_.factors.size());
  ids.clear();
  ids.reserve(graph_.factors.size());
  for (size_t i = 0; i < graph_.factors.size(); ++i) {
    if (outlier(i)) continue;
    pass.factors.push_back(graph_.factors[i]);
    ids.push_back(i);
  }
  pass.poses = std::move(graph_.poses);
  if (config_.share_loop_information) graph::share_loop_information(pass, loop_counts_);
  return pass;
}

UpdateStats CentralCore::solve_with(const graph::SolverOptions& options) {
  UpdateStats st;
  st.poses = graph_.poses.size();
  st.factors = graph_.factors.size();
  if (graph_.factors.empty()) {
    return st;
  }
  std::vector<size_t> ids;
  graph::PoseGraph pass = take_pass_graph(ids);
  const graph::SolveResult r = graph::solve(pass, options);
  review_loops(pass, ids, r);
  graph_.poses = std::move(pass.poses);
  st.solved = true;
  st.converged = r.converged;
  st.iterations = r.iterations;
  st.time_s = r.time_s;
  st.cost = r.final_cost;
  ++version_;
  dirty_ = false;
  touched_.clear();
  updates_since_full_ = 0;
  changes_since_full_ = 0;
  need_full_ = false;
  for (auto& [robot, list] : sessions_) {
    for (Session& s : list) s.inserted_since_full = 0;
  }
  settled_ = r.converged;
  last_full_ = true;
  st.full = true;
  return st;
}

// Every touched key and the `window` keyframes before it on the same robot session.
std::set<Key> CentralCore::active_keys() const {
  std::set<Key> active;
  for (Key k : touched_) {
    const uint64_t idx = graph::index_of(k);
    const uint64_t id = idx & 0xffffffffu;
    const uint64_t first = id > config_.window ? id - config_.window : 0;
    for (uint64_t i = first; i <= id; ++i) {
      const Key a = graph::make_key(graph::robot_of(k), (idx & ~uint64_t{0xffffffffu}) | i);
      if (graph_.poses.count(a) != 0) {
        active.insert(a);
      }
    }
  }
  return active;
}

// The factors of a local pass: every factor between two active keys, and of those that tie an active
// key to a fixed one (loops to earlier laps), the kMaxAnchorsPerKey most recent per key. A place
// revisited lap after lap gathers a loop per visit; all of them would make each local pass grow with
// the mission, while a few recent ones hold the window as well (the full passes take them all).
std::vector<size_t> CentralCore::local_factors(const std::set<Key>& active) const {
  std::vector<size_t> through;
  for (Key k : active) {
    const auto it = factors_at_.find(k);
    if (it == factors_at_.end()) continue;
    size_t anchors = 0;
    for (auto i = it->second.rbegin(); i != it->second.rend(); ++i) {  // newest first
      if (outlier(*i)) continue;
      const graph::Factor& f = graph_.factors[*i];
      const bool inside = active.count(f.a) != 0 && active.count(f.b) != 0;
      if (inside || f.kind != graph::FactorKind::kLoop || anchors++ < kMaxAnchorsPerKey) through.push_back(*i);
    }
  }
  std::sort(through.begin(), through.end());
  through.erase(std::unique(through.begin(), through.end()), through.end());
  return through;
}

// The active keys and the factors through them (local_factors), the keys beyond held fixed: the work
// is the window's, whatever the size of the graph. A pass that does not converge keeps its touched
// keys, so that the next update goes on with them.
UpdateStats CentralCore::solve_local(const graph::SolverOptions& options) {
  const std::set<Key> active = active_keys();
  const std::vector<size_t> through = local_factors(active);
  graph::PoseGraph local;
  local.dimension = graph_.dimension;
  std::set<Key> fixed;
  for (size_t i : through) {
    const graph::Factor& f = graph_.factors[i];
    local.factors.push_back(f);
    for (Key k : {f.a, f.b}) {
      local.poses[k] = graph_.poses.at(k);
      if (active.count(k) == 0) fixed.insert(k);
    }
  }
  UpdateStats st;
  st.poses = active.size();
  st.factors = local.factors.size();
  if (!local.factors.empty()) {
    if (config_.share_loop_information) graph::share_loop_information(local, loop_counts_);
    if (fixed.empty() && local.count(graph::FactorKind::kPrior) == 0) fixed.insert(local.poses.begin()->first);
    const graph::SolveResult r = graph::solve(local, options, fixed);
    for (Key k : active) graph_.poses[k] = local.poses.at(k);
    st.solved = true;
    st.converged = r.converged;
    st.iterations = r.iterations;
    st.time_s = r.time_s;
  }
  st.cost = 0.0;
  ++version_;
  ++updates_since_full_;
  dirty_ = false;
  if (st.converged) {
    touched_.clear();
  } else if (touched_.size() > kMaxCarriedTouched * (size_t{config_.window} + 1)) {
    need_full_ = true;  // passes that keep falling short: a full pass settles what they carry
  }
  settled_ = st.converged;
  last_full_ = false;
  return st;
}

// A full pass is due for a joining robot or a backlog (need_full_), to go on with a full pass that
// did not converge, and periodically once the graph has changed by full_growth of its size.
bool CentralCore::full_pass_due() const {
  if (need_full_ || (!settled_ && last_full_)) return true;
  const double grown = config_.full_growth * static_cast<double>(graph_.poses.size());
  return updates_since_full_ + 1 >= config_.full_every && static_cast<double>(changes_since_full_) >= grown;
}

graph::SolverOptions CentralCore::update_options() const {
  graph::SolverOptions o;
  o.max_iterations = config_.max_iterations_per_update;
  o.max_time_s = config_.max_time_per_update_s;
  o.function_tolerance = 1e-8;
  o.robust_loss_scale = config_.loop_robust_scale;
  o.on_iteration = on_iteration_;
  return o;
}

UpdateStats CentralCore::optimise() {
  graph::SolverOptions o = update_options();
  if (full_pass_due()) {
    // A full pass is warm-started and bounded by its iterations: successive passes converge, and
    // the work loop is never blocked for long (on_iteration reports its progress).
    o.max_iterations = std::min(o.max_iterations, config_.full_pass_iterations);
    o.max_time_s = config_.full_pass_time_s;
    return solve_with(full_pass_options(o));
  }
  return solve_local(o);
}

UpdateStats CentralCore::optimise_fully() {
  graph::SolverOptions o;
  o.on_iteration = on_iteration_;
  o.max_iterations = 500;
  o.function_tolerance = 1e-14;
  o.gradient_tolerance = 1e-14;
  o.parameter_tolerance = 1e-14;
  o.robust_loss_scale = config_.loop_robust_scale;
  // Loops that rejoin after a pass are in the next one: the final solve takes them in.
  UpdateStats st = solve_with(full_pass_options(o));
  for (int again = 0; again <= kGncMaxRetries && rejoined_ > 0; ++again) st = solve_with(full_pass_options(o));
  return st;
}

std::vector<LoopIn> CentralCore::outlier_loops() const {
  std::vector<LoopIn> out;
  for (const StoredLoop& l : loops_) {
    if (l.in_graph && outlier(l.factor_index)) out.push_back(l.in);
  }
  return out;
}

graph::SolverOptions CentralCore::full_pass_options(graph::SolverOptions o) const {
  if (!config_.loop_gnc) return o;
  o.gnc.enabled = true;
  o.gnc.least_squares_start = true;
  o.gnc.require_converged_start = true;
  o.gnc.inlier_threshold = gnc_threshold_;
  o.gnc.mu_step = 2.0;
  o.gnc.max_rounds = config_.loop_gnc_rounds;
  return o;
}

// After a full pass with GNC that converged: the outliers held out before it that lie within c^2 of
// its solution rejoin the graph (or try again, see below), the loops its weights reject are held out, and the accepted
// loops' median squared residual sets the next pass's threshold. A pass cut short decides nothing.
void CentralCore::review_loops(const graph::PoseGraph& pass, const std::vector<size_t>& ids,
                               const graph::SolveResult& r) {
  rejoined_ = 0;
  if (!config_.loop_gnc || r.failed || !r.converged || !r.gnc_converged || r.weights.size() != pass.factors.size()) {
    return;
  }
  outliers_.resize(graph_.factors.size(), 0);
  retries_.resize(graph_.factors.size(), 0);
  for (size_t i = 0; i < outliers_.size(); ++i) {
    if (outliers_[i] == 0) continue;
    graph::Factor f = graph_.factors[i];
    if (config_.share_loop_information) graph::share_loop_information(f, loop_counts_);
    // Held out while wrong loops bent the graph, a true loop may sit a little beyond c^2 of the
    // graph without it and within c^2 with it: such loops take part in GNC again (a few times).
    const double s = graph::squared_residual(pass, f);
    const bool retry = s <= kGncRetryFactor * gnc_threshold_ && retries_[i] < kGncMaxRetries;
    if (s <= gnc_threshold_ || retry) {
      if (s > gnc_threshold_) ++retries_[i];
      outliers_[i] = 0;
      --counters_.loops_outliers;
      ++rejoined_;
    }
  }
  std::vector<double> accepted;
  for (size_t j = 0; j < pass.factors.size(); ++j) {
    if (!pass.factors[j].robust) continue;
    if (r.weights[j] < graph::kGncAcceptedWeight) {
      outliers_[ids[j]] = 1;
      ++counters_.loops_outliers;
    } else {
      accepted.push_back(graph::squared_residual(pass, pass.factors[j]));
    }
  }
  if (accepted.size() < kGncCalibrationLoops) return;
  const auto mid = accepted.begin() + static_cast<std::ptrdiff_t>(accepted.size() / 2);
  std::nth_element(accepted.begin(), mid, accepted.end());
  gnc_threshold_ = std::min(config_.loop_gnc_threshold, config_.loop_gnc_median_ratio * *mid);
}

std::vector<RobotEstimate> CentralCore::estimates() const {
  std::vector<RobotEstimate> out;
  for (const auto& entry : sessions_) {
    if (std::optional<RobotEstimate> e = estimate(entry.first)) out.push_back(std::move(*e));
  }
  return out;
}

// One pass over the robot's keyframes in the graph and its held odometry, both in id order.
std::optional<RobotEstimate> CentralCore::estimate(uint32_t robot) const {
  auto it = sessions_.find(robot);
  if (it == sessions_.end() || it->second.empty()) return std::nullopt;
  const Session& s = it->second.back();
  RobotEstimate e;
  e.robot = robot;
  e.incarnation = s.incarnation;
  if (s.placed && s.in_graph > 0) {
    e.poses.reserve(s.in_graph);
    // W from the robot's odometry frame (paper eq. 1-2), fitted to all its keyframes in the graph
    // rather than held at the first: a new loop that turns the robot's whole trajectory about its
    // first keyframe moves no corrected pose relative to the others. Only the change in shape (drift
    // corrected along the trajectory) reaches the front-end, whose fusion takes it up.
    geometry::PoseAligner fit;
    auto pose = graph_.poses.find(key(s, 0));
    auto held = s.keyframes.begin();
    for (uint32_t id = 0; id < s.in_graph; ++id, ++pose, ++held) {
      e.poses.emplace_back(id, pose->second);
      fit.add(held->second.T_odom_keyframe, pose->second);
    }
    const geometry::Alignment a = fit.solve();
    e.T_world_robot =
        a.ok ? a.T_dst_src : e.poses.front().second * s.keyframes.begin()->second.T_odom_keyframe.inverse();
  } else if (s.hint) {
    e.T_world_robot = *s.hint;
    e.from_hint = true;
    e.poses.reserve(s.keyframes.size());
    for (const auto& [id, kf] : s.keyframes) e.poses.emplace_back(id, *s.hint * kf.T_odom_keyframe);
  } else {
    return std::nullopt;  // not in the world yet
  }
  return e;
}

std::vector<Acknowledgement> CentralCore::acknowledgements() const {
  std::vector<Acknowledgement> out;
  for (const auto& [robot, list] : sessions_) {
    for (const Session& s : list) {
      Acknowledgement a;
      a.robot = robot;
      a.incarnation = s.incarnation;
      a.highest_contiguous_keyframe = static_cast<int64_t>(s.contiguous) - 1;
      a.highest_contiguous_loop_seq = s.loop_contiguous;
      out.push_back(a);
    }
  }
  return out;
}

std::optional<Eigen::Vector3d> CentralCore::newest_position(uint32_t robot) const {
  auto it = sessions_.find(robot);
  if (it == sessions_.end() || it->second.empty()) return std::nullopt;
  const Session& s = it->second.back();
  if (s.placed && s.in_graph > 0) return graph_.poses.at(key(s, s.in_graph - 1)).translation();
  if (s.hint && s.contiguous > 0) {
    return (*s.hint * s.keyframes.at(static_cast<uint32_t>(s.contiguous - 1)).T_odom_keyframe).translation();
  }
  return std::nullopt;
}

size_t CentralCore::keyframes_held(uint32_t robot, uint32_t incarnation) const {
  auto it = sessions_.find(robot);
  if (it == sessions_.end()) {
    return 0;
  }
  for (const Session& s : it->second) {
    if (s.incarnation == incarnation) {
      return s.keyframes.size();
    }
  }
  return 0;
}

}  // namespace cdc::central
