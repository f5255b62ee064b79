// cdc-peer-replay: the distributed back-end of a run, without DDS and without a central. Replays a
// multi-robot pose graph (g2o, as the central writes it) through one PeerCore per robot: keyframes
// arrive at their stamps, each loop once both its keyframes exist (plus a latency and a seeded
// jitter), and every robot's separators reach their targets after each tick, as the nodes exchange
// them. Every robot steps at once, as the nodes do. Reports per robot the ATE of the odometry, of the
// keyframes where the corrections had placed them when they were made (the real-time view), and of
// the final estimate; and the joint cost of the distributed estimate against the centralized optimum.
#include "cdc/base/cli.hpp"
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"
#include "cdc/peer_optimiser/peer_core.hpp"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

using namespace cdc;

namespace {

using Stamped = std::vector<std::pair<double, Eigen::Vector3d>>;  // seconds, position

struct TimedLoop {
  double available_s = 0;
  peer::LoopRecord record;
};

// A run's radio timeline (cdc-launch's links.csv: wall_s,sim_s,a,b,state): which robot pairs could talk
// when. A pair with no row is up.
class RadioTimeline {
 public:
  void load(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw std::runtime_error(path + ": cannot be read");
    std::string line;
    size_t n = 0;
    while (std::getline(in, line)) {
      ++n;
      if (n == 1 || line.empty()) continue;  // the header
      std::istringstream row(line);
      std::string wall, sim, a, b, state;
      if (!std::getline(row, wall, ',') || !std::getline(row, sim, ',') || !std::getline(row, a, ',') ||
          !std::getline(row, b, ',') || !std::getline(row, state) || (state != "up" && state != "down")) {
        throw std::runtime_error(path + ":" + std::to_string(n) + ": expected wall_s,sim_s,a,b,up|down");
      }
      const auto ra = static_cast<uint32_t>(std::stoul(a)), rb = static_cast<uint32_t>(std::stoul(b));
      changes_[{std::min(ra, rb), std::max(ra, rb)}].emplace_back(std::stod(sim), state == "up");
    }
  }
  bool up(uint32_t a, uint32_t b, double t) const {
    const auto it = changes_.find({std::min(a, b), std::max(a, b)});
    if (it == changes_.end()) return true;
    bool state = true;
    for (const auto& [at, is_up] : it->second) {
      if (at > t) break;
      state = is_up;
    }
    return state;
  }
  // The first time from t on when the pair is up; infinity if never again.
  double next_up(uint32_t a, uint32_t b, double t) const {
    if (up(a, b, t)) return t;
    const auto it = changes_.find({std::min(a, b), std::max(a, b)});
    for (const auto& [at, is_up] : it->second) {
      if (at > t && is_up) return at;
    }
    return HUGE_VAL;
  }

 private:
  std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<double, bool>>> changes_;
};

// ATE [m] (SE(3)-aligned) of stamped positions against a ground-truth trajectory; NaN below 3 pairs.
double ate_of(const Stamped& est, const geometry::Trajectory& gt) {
  geometry::Poses e, g;
  for (const auto& [t, p] : est) {
    if (const auto T = geometry::interpolate_at(gt, std::llround(t * 1e9))) {
      Eigen::Isometry3d E = Eigen::Isometry3d::Identity();
      E.translation() = p;
      e.push_back(E);
      g.push_back(*T);
    }
  }
  if (e.size() < 3) return NAN;
  return geometry::compute_ate(e, g, geometry::AlignMode::kSE3).translation.rmse;
}

// The command line.
struct ReplayOptions {
  std::vector<std::string> graph_paths;
  std::string run_dir, truth_dir, links_path;
  double latency_s = 1.0, jitter_s = 0.0, tail_s = 30.0;
  uint32_t robots = 3, seed = 1;
  int round_ms = 200;
  double refresh_s = std::chrono::duration<double>(peer::PeerConfig{}.separator_refresh).count();
  bool verbose = false;
  peer::PeerConfig base;  // every robot's configuration but its id
};

// What to replay.
void add_run_options(CLI::App& app, ReplayOptions& o) {
  base::add_input(app, "GRAPH", o.graph_paths,
                  "g2o graph(s) holding every robot's keyframes and loops: a run's global_graph.g2o, or its "
                  "robot_N/peer_graph.g2o files together (merged; a factor in several is kept once)");
  base::add_input(app, "--run", o.run_dir, "the run's folder: robot_N/keyframes.tum gives each keyframe's stamp",
                  CLI::ExistingDirectory);
  base::add_input(app, "--truth", o.truth_dir, "the dataset's folder: robot_N/groundtruth.tum", CLI::ExistingDirectory);
  base::add_setting(app, "--robots", o.robots, "robots in the graph", config::cli_range(1, 64));
}

// When loops arrive, and how long the replay goes on.
void add_timing_options(CLI::App& app, ReplayOptions& o) {
  base::add_setting(app, "--loop-latency", o.latency_s, "seconds from a loop's later keyframe to its arrival",
                    config::cli_range(0, 3600));
  base::add_setting(app, "--jitter", o.jitter_s, "a uniform extra loop latency up to this many seconds (seeded)",
                    config::cli_range(0, 3600));
  base::add_setting(app, "--seed", o.seed, "seed of the jitter", config::cli_range(0, 4294967295));
  base::add_setting(app, "--tail", o.tail_s, "seconds of rounds after the last keyframe", config::cli_range(0, 1e5));
}

// The keys of peer_optimiser.yaml the replay takes.
void add_peer_options(CLI::App& app, ReplayOptions& o) {
  base::add_setting(app, "--round-ms", o.round_ms, "distributed round period (peer_optimiser.yaml's round_period_ms)",
                    config::cli_range(1, 100000));
  base::add_setting(app, "--iterations", o.base.distributed_iterations,
                    "solver iterations per round (distributed_iterations)", config::cli_range(1, 1000));
  base::add_setting(app, "--relaxation", o.base.relaxation,
                    "fraction of each round's step taken (distributed_relaxation)", config::cli_range(1e-3, 1));
  base::add_setting(
      app, "--separator-min-change", o.base.separator_min_change_m,
      "a separator pose is sent again once it moved this far [m] (separator_min_change_m; the angle scales with it)",
      config::cli_range(0, 100));
  base::add_setting(
      app, "--separator-refresh", o.refresh_s,
      "every this many seconds a peer gets all its separator poses (separator_refresh_ms / 1000); it gets "
      "them too whenever its link comes back up, as a peer's reader matched anew does",
      config::cli_range(0.01, 3600));
}

// The parsed periods into the peers' configuration.
void apply_peer_options(ReplayOptions& o) {
  o.base.round_period = std::chrono::milliseconds(o.round_ms);
  o.base.separator_refresh = std::chrono::duration_cast<peer::Nanos>(std::chrono::duration<double>(o.refresh_s));
  o.base.separator_min_change_rad *= o.base.separator_min_change_m / peer::PeerConfig{}.separator_min_change_m;
}

// What the replay reads: the swarm's graph, each keyframe's stamp, the ground truth, the radio timeline.
struct RunData {
  graph::PoseGraph graph;
  // A peer graph holds its robot's keyframes (most of its vertices) where that robot's live estimate
  // put them, and its peers' separators as last received: the run's own estimate is each robot's
  // keyframes taken from its own graph.
  std::map<graph::Key, Eigen::Isometry3d> live;
  std::vector<std::vector<double>> stamps;  // per robot, its keyframes' stamps [s]
  std::vector<geometry::Trajectory> truth;  // per robot
  RadioTimeline radio;

  double stamp_of(graph::Key k) const {
    const uint64_t i = graph::index_of(k);
    const auto& s = stamps[graph::robot_of(k)];
    return i < s.size() ? s[i] : HUGE_VAL;
  }
};

// The graphs merged (a factor in several kept once, priors dropped), and each graph's own robot's
// keyframes (the robot with most vertices in it) as `live`.
void merge_graphs(const std::vector<std::string>& paths, RunData& run) {
  std::set<std::pair<graph::Key, graph::Key>> factors_seen;
  for (const std::string& path : paths) {
    graph::PoseGraph part = graph::read_g2o(path);
    std::map<uint64_t, size_t> per_robot;
    for (const auto& [k, _] : part.poses) ++per_robot[graph::robot_of(k)];
    const auto owner = std::max_element(per_robot.begin(), per_robot.end(),
                                        [](const auto& a, const auto& b) { return a.second < b.second; });
    for (const auto& [k, T] : part.poses) {
      if (owner != per_robot.end() && graph::robot_of(k) == owner->first) run.live[k] = T;
    }
    run.graph.poses.insert(part.poses.begin(), part.poses.end());
    for (const graph::Factor& f : part.factors) {
      if (f.kind != graph::FactorKind::kPrior && factors_seen.insert({f.a, f.b}).second) run.graph.factors.push_back(f);
    }
  }
}

RunData read_run(const ReplayOptions& o) {
  RunData run;
  merge_graphs(o.graph_paths, run);
  run.stamps.resize(o.robots);
  run.truth.resize(o.robots);
  for (uint32_t r = 0; r < o.robots; ++r) {
    const std::string dir = "/robot_" + std::to_string(r);
    for (const auto& p : geometry::read_tum(o.run_dir + dir + "/keyframes.tum")) {
      run.stamps[r].push_back(static_cast<double>(p.stamp_ns) * 1e-9);
    }
    run.truth[r] = geometry::read_tum(o.truth_dir + dir + "/groundtruth.tum");
  }
  for (const auto& [k, _] : run.graph.poses) {
    if (graph::robot_of(k) >= o.robots) {
      throw std::runtime_error("the graph holds robot " + std::to_string(graph::robot_of(k)) + "; --robots is " +
                               std::to_string(o.robots));
    }
  }
  if (!o.links_path.empty()) run.radio.load(o.links_path);
  return run;
}

// What arrives when: each robot's keyframes (their odometry chained from the graph's odometry factors)
// and the loops by arrival time; and the centralized problem the rounds should reach.
struct Schedule {
  std::vector<std::map<uint32_t, peer::OwnKeyframe>> keyframes;  // per robot
  std::vector<TimedLoop> loops;
  graph::PoseGraph central;
};

// Each loop once its later keyframe is made, plus the latency and a seeded jitter. An inter-robot loop
// is verified with the other robot's cloud: not before their link is up.
std::vector<TimedLoop> loop_arrivals(const RunData& run, const ReplayOptions& o) {
  std::vector<TimedLoop> loops;
  std::mt19937 rng(o.seed);
  std::uniform_real_distribution<double> jitter(0.0, o.jitter_s);
  for (const graph::Factor& f : run.graph.factors) {
    if (f.kind != graph::FactorKind::kLoop) continue;
    peer::LoopRecord l;
    l.sender = static_cast<uint32_t>(graph::robot_of(f.b));
    l.seq = static_cast<uint32_t>(loops.size());
    l.robot_a = static_cast<uint32_t>(graph::robot_of(f.a));
    l.keyframe_a = static_cast<uint32_t>(graph::index_of(f.a));
    l.robot_b = static_cast<uint32_t>(graph::robot_of(f.b));
    l.keyframe_b = static_cast<uint32_t>(graph::index_of(f.b));
    l.T_a_b = f.measurement;
    l.information = f.information;
    const double t = std::max(run.stamp_of(f.a), run.stamp_of(f.b)) + o.latency_s + jitter(rng);
    loops.push_back({run.radio.next_up(l.robot_a, l.robot_b, t), l});
  }
  std::stable_sort(loops.begin(), loops.end(),
                   [](const auto& a, const auto& b) { return a.available_s < b.available_s; });
  return loops;
}

std::vector<std::map<uint32_t, peer::OwnKeyframe>> chain_odometry(const graph::PoseGraph& g, uint32_t robots) {
  std::vector<std::map<uint32_t, peer::OwnKeyframe>> keyframes(robots);
  for (auto& k : keyframes) k[0] = peer::OwnKeyframe{};
  std::vector<const graph::Factor*> odometry;
  for (const graph::Factor& f : g.factors) {
    if (f.kind == graph::FactorKind::kOdometry) odometry.push_back(&f);
  }
  std::sort(odometry.begin(), odometry.end(), [](const auto* a, const auto* b) { return a->b < b->b; });
  for (const graph::Factor* f : odometry) {
    auto& own = keyframes[graph::robot_of(f->a)];
    const auto id = static_cast<uint32_t>(graph::index_of(f->b));
    if (const auto prev = own.find(id - 1); id > 0 && prev != own.end()) {
      own[id] = peer::OwnKeyframe{id, 0, 0, prev->second.T_odom * f->measurement, f->measurement, f->information};
    }
  }
  return keyframes;
}

Schedule make_schedule(const RunData& run, const ReplayOptions& o) {
  Schedule s;
  s.loops = loop_arrivals(run, o);
  s.keyframes = chain_odometry(run.graph, o.robots);
  // The centralized problem: the same loops, weighed as the peers weigh them.
  s.central = run.graph;
  if (o.base.share_loop_information) graph::share_loop_information(s.central);
  s.central.add_prior(graph::make_key(0, 0), s.keyframes[0].at(0).T_odom, graph::Matrix6d::Identity() * 1e6);
  return s;
}

// One PeerCore per robot, stepped together every 50 ms of replayed time: keyframes arrive at their
// stamps, loops at their arrival, and each robot's separators reach their targets after every tick
// while the pair's link is up.
class Replay {
 public:
  static constexpr double kTickSeconds = 0.05;
  static constexpr int64_t kTickNanos = 50'000'000;

  Replay(const ReplayOptions& o, const RunData& data, const Schedule& schedule)
      : o_(o),
        run_(data),
        schedule_(schedule),
        next_(o.robots, 0),
        realtime_(o.robots),
        odom_(o.robots),
        separator_poses_(o.robots, 0),
        link_up_(o.robots, std::vector<bool>(o.robots, true)),
        last_(o.robots) {
    for (uint32_t r = 0; r < o.robots; ++r) {
      peer::PeerConfig c = o.base;
      c.robot = r;
      c.robot_count = o.robots;
      c.rtdos.range_m = 1e9;
      cores_.emplace_back(c);
    }
  }

  void run() {
    double end_s = 0;
    for (const auto& s : run_.stamps) end_s = std::max(end_s, s.empty() ? 0.0 : s.back());
    const long ticks = std::lround((end_s + o_.tail_s) / kTickSeconds);
    for (long tick = 0; tick <= ticks; ++tick) {
      const double t = static_cast<double>(tick) * kTickSeconds;
      const peer::Nanos now{static_cast<int64_t>(tick) * kTickNanos};
      deliver_keyframes(t, now);
      deliver_loops(t, now);
      rejoin_links(t);
      step_all(t, now);
      if (o_.verbose && tick % 100 == 0) std::printf("t %.0f s: joint cost %.2f\n", t, joint_cost());
    }
  }

  // The joint cost of the centralized problem at each robot's last corrected keyframe poses.
  double joint_cost() const {
    graph::PoseGraph joint = schedule_.central;
    for (uint32_t r = 0; r < o_.robots; ++r) {
      if (last_[r]) {
        for (const auto& [id, T] : last_[r]->poses) joint.poses[graph::make_key(r, id)] = T;
      }
    }
    return graph::full_information_cost(joint);
  }

  // Per robot: its keyframes at their odometry, where the front-end put them when they were made, and
  // where the last correction has them.
  const Stamped& odometry(uint32_t r) const { return odom_[r]; }
  const Stamped& realtime(uint32_t r) const { return realtime_[r]; }
  Stamped final_estimate(uint32_t r) const {
    Stamped out;
    if (last_[r]) {
      for (const auto& [id, P] : last_[r]->poses) {
        if (id < run_.stamps[r].size()) out.emplace_back(run_.stamps[r][id], P.translation());
      }
    }
    return out;
  }
  uint64_t rounds(uint32_t r) const { return cores_[r].distributed_rounds(); }
  size_t separator_poses(uint32_t r) const { return separator_poses_[r]; }

 private:
  void deliver_keyframes(double t, peer::Nanos now) {
    for (uint32_t r = 0; r < o_.robots; ++r) {
      const auto& stamps = run_.stamps[r];
      const auto& keyframes = schedule_.keyframes[r];
      for (; next_[r] < stamps.size() && stamps[next_[r]] <= t && keyframes.count(next_[r]) != 0; ++next_[r]) {
        const peer::OwnKeyframe& k = keyframes.at(next_[r]);
        cores_[r].add_keyframe(k, now);
        odom_[r].emplace_back(stamps[next_[r]], k.T_odom.translation());
        // Where the front-end puts this keyframe: the newest corrected keyframe, as
        // T_world_robot^-1 * pose, carried on by the odometry.
        Eigen::Isometry3d T = k.T_odom;
        if (last_[r] && !last_[r]->poses.empty()) {
          const auto& [id, P] = last_[r]->poses.back();
          T = last_[r]->T_world_robot.inverse() * P * keyframes.at(id).T_odom.inverse() * k.T_odom;
        }
        realtime_[r].emplace_back(stamps[next_[r]], T.translation());
      }
    }
  }

  void deliver_loops(double t, peer::Nanos now) {
    for (; next_loop_ < schedule_.loops.size() && schedule_.loops[next_loop_].available_s <= t; ++next_loop_) {
      const peer::LoopRecord& l = schedule_.loops[next_loop_].record;
      cores_[l.robot_a].add_loop(l, now);
      if (l.robot_b != l.robot_a) cores_[l.robot_b].add_loop(l, now);
    }
  }

  // A link back up: each end's reader matches anew, and the other end sends it every separator.
  void rejoin_links(double t) {
    for (uint32_t a = 0; a < o_.robots; ++a) {
      for (uint32_t b = a + 1; b < o_.robots; ++b) {
        const bool up = run_.radio.up(a, b, t);
        if (up && !link_up_[a][b]) {
          cores_[a].resend_separators_to(b);
          cores_[b].resend_separators_to(a);
        }
        link_up_[a][b] = up;
      }
    }
  }

  // Every robot steps at once, as the nodes do; then the separators cross.
  void step_all(double t, peer::Nanos now) {
    std::vector<peer::StepOutput> out;
    for (auto& c : cores_) out.push_back(c.step(now, false));
    for (uint32_t r = 0; r < o_.robots; ++r) {
      for (const auto& s : out[r].separators) {
        if (!run_.radio.up(r, s.target, t)) continue;
        cores_[s.target].on_separator(r, s);
        separator_poses_[r] += s.poses.size();
      }
      if (out[r].correction) last_[r] = std::move(out[r].correction);
    }
  }

  const ReplayOptions& o_;
  const RunData& run_;
  const Schedule& schedule_;
  std::vector<peer::PeerCore> cores_;
  std::vector<uint32_t> next_;  // per robot, its next keyframe
  size_t next_loop_ = 0;
  std::vector<Stamped> realtime_, odom_;
  std::vector<size_t> separator_poses_;  // per robot, sent
  std::vector<std::vector<bool>> link_up_;
  std::vector<std::optional<peer::Correction>> last_;  // per robot, its last correction
};

// Per robot its ATEs, and the joint cost against the centralized optimum; given the peers' graphs
// together, the run's own estimate too.
void report(const Replay& replay, const RunData& run, const Schedule& schedule, const ReplayOptions& o) {
  for (uint32_t r = 0; r < o.robots; ++r) {
    std::printf(
        "robot %u: %zu keyframes, %llu rounds, %zu separator poses sent; ATE odometry %.4f, real-time %.4f, final %.4f "
        "m\n",
        r, replay.odometry(r).size(), static_cast<unsigned long long>(replay.rounds(r)), replay.separator_poses(r),
        ate_of(replay.odometry(r), run.truth[r]), ate_of(replay.realtime(r), run.truth[r]),
        ate_of(replay.final_estimate(r), run.truth[r]));
  }
  graph::PoseGraph optimum = schedule.central;
  graph::SolverOptions so;
  so.robust_loss_scale = 0.0;  // as the rounds solve
  graph::solve(optimum, so);
  std::printf("joint cost: distributed %.2f, centralized optimum %.2f\n", replay.joint_cost(),
              graph::full_information_cost(optimum));
  if (o.graph_paths.size() < 2 || run.live.size() != run.graph.poses.size()) return;
  graph::PoseGraph own_estimate = schedule.central;
  for (const auto& [k, T] : run.live) own_estimate.poses[k] = T;
  std::printf("joint cost of the run's own estimate (each robot's keyframes from its graph): %.2f\n",
              graph::full_information_cost(own_estimate));
  std::vector<Stamped> own(o.robots);
  for (const auto& [k, T] : run.live) own[graph::robot_of(k)].emplace_back(run.stamp_of(k), T.translation());
  for (uint32_t r = 0; r < o.robots; ++r)
    std::printf("robot %u: ATE of the run's own estimate %.4f m\n", r, ate_of(own[r], run.truth[r]));
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "Replays a run's multi-robot pose graph through the peer optimisers' distributed rounds (no central, "
      "no DDS) and reports how close they come to the centralized optimum"};
  ReplayOptions o;
  add_run_options(app, o);
  add_timing_options(app, o);
  add_peer_options(app, o);
  app.add_option(
         "--links", o.links_path,
         "the run's links.csv: separators cross, and inter-robot loops arrive, only while the pair's link is up "
         "(default: every link up)")
      ->check(CLI::ExistingFile);
  app.add_flag("--verbose", o.verbose, "print the joint cost every 5 s of replayed time");
  CLI11_PARSE(app, argc, argv);
  apply_peer_options(o);
  return base::run_tool(
      "cdc-peer-replay",
      [&] {
        const RunData run = read_run(o);
        const Schedule schedule = make_schedule(run, o);
        Replay replay(o, run, schedule);
        replay.run();
        report(replay, run, schedule, o);
        return 0;
      },
      [](const std::exception&) { return 2; });
}
