// cdc-peer-replay: the distributed back-end of a run, without DDS and without a central. Replays a
// multi-robot pose graph (g2o, as the central writes it) through one PeerCore per robot: keyframes
// arrive at their stamps, each loop once both its keyframes exist (plus a latency and a seeded
// jitter), and every robot's separators reach their targets after each tick, as the nodes exchange
// them. Every robot steps at once, as the nodes do. Reports per robot the ATE of the odometry, of the
// keyframes where the corrections had placed them when they were made (the real-time view), and of
// the final estimate; and the joint cost of the distributed estimate against the centralized optimum.
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

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Replays a run's multi-robot pose graph through the peer optimisers' distributed rounds (no central, "
               "no DDS) and reports how close they come to the centralized optimum"};
  std::vector<std::string> graph_paths;
  std::string run_dir, truth_dir, links_path;
  double latency_s = 1.0, jitter_s = 0.0, tail_s = 30.0;
  uint32_t robots = 3, seed = 1;
  int round_ms = 200;
  bool verbose = false;
  peer::PeerConfig base;
  app.add_option("GRAPH", graph_paths,
                 "g2o graph(s) holding every robot's keyframes and loops: a run's global_graph.g2o, or its "
                 "robot_N/peer_graph.g2o files together (merged; a factor in several is kept once)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--run", run_dir, "the run's folder: robot_N/keyframes.tum gives each keyframe's stamp")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--truth", truth_dir, "the dataset's folder: robot_N/groundtruth.tum")
      ->required()
      ->check(CLI::ExistingDirectory);
  app.add_option("--robots", robots, "robots in the graph")->capture_default_str()->check(CLI::Range(1, 64));
  app.add_option("--loop-latency", latency_s, "seconds from a loop's later keyframe to its arrival")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--jitter", jitter_s, "a uniform extra loop latency up to this many seconds (seeded)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--seed", seed, "seed of the jitter")->capture_default_str();
  app.add_option("--tail", tail_s, "seconds of rounds after the last keyframe")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--round-ms", round_ms, "distributed round period (peer_optimiser.yaml's round_period_ms)")
      ->capture_default_str()
      ->check(CLI::Range(1, 100000));
  app.add_option("--iterations", base.distributed_iterations, "solver iterations per round (distributed_iterations)")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000));
  app.add_option("--relaxation", base.relaxation, "fraction of each round's step taken (distributed_relaxation)")
      ->capture_default_str()
      ->check(CLI::Range(1e-3, 1.0));
  app.add_option("--separator-min-change", base.separator_min_change_m,
                 "a separator pose is sent again once it moved this far [m] (separator_min_change_m; the angle scales with it)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  double refresh_s = std::chrono::duration<double>(base.separator_refresh).count();
  app.add_option("--separator-refresh", refresh_s,
                 "every this many seconds a peer gets all its separator poses (separator_refresh_ms / 1000); it gets "
                 "them too whenever its link comes back up, as a peer's reader matched anew does")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--links", links_path,
                 "the run's links.csv: separators cross, and inter-robot loops arrive, only while the pair's link is up "
                 "(default: every link up)")
      ->check(CLI::ExistingFile);
  app.add_flag("--verbose", verbose, "print the joint cost every 5 s of replayed time");
  CLI11_PARSE(app, argc, argv);
  base.round_period = std::chrono::milliseconds(round_ms);
  base.separator_refresh = std::chrono::duration_cast<peer::Nanos>(std::chrono::duration<double>(refresh_s));
  base.separator_min_change_rad *= base.separator_min_change_m / peer::PeerConfig{}.separator_min_change_m;

  try {
    graph::PoseGraph g;
    std::set<std::pair<graph::Key, graph::Key>> factors_seen;
    // A peer graph holds its robot's keyframes (most of its vertices) where that robot's live estimate
    // put them, and its peers' separators as last received: the run's own estimate is each robot's
    // keyframes taken from its own graph.
    std::map<graph::Key, Eigen::Isometry3d> live;
    for (const std::string& path : graph_paths) {
      graph::PoseGraph part = graph::read_g2o(path);
      std::map<uint64_t, size_t> per_robot;
      for (const auto& [k, _] : part.poses) ++per_robot[graph::robot_of(k)];
      const auto owner = std::max_element(per_robot.begin(), per_robot.end(),
                                          [](const auto& a, const auto& b) { return a.second < b.second; });
      for (const auto& [k, T] : part.poses) {
        if (owner != per_robot.end() && graph::robot_of(k) == owner->first) live[k] = T;
      }
      g.poses.insert(part.poses.begin(), part.poses.end());
      for (const graph::Factor& f : part.factors) {
        if (f.kind != graph::FactorKind::kPrior && factors_seen.insert({f.a, f.b}).second) g.factors.push_back(f);
      }
    }
    std::vector<std::vector<double>> stamps(robots);
    std::vector<geometry::Trajectory> truth(robots);
    for (uint32_t r = 0; r < robots; ++r) {
      const std::string dir = "/robot_" + std::to_string(r);
      for (const auto& p : geometry::read_tum(run_dir + dir + "/keyframes.tum")) stamps[r].push_back(static_cast<double>(p.stamp_ns) * 1e-9);
      truth[r] = geometry::read_tum(truth_dir + dir + "/groundtruth.tum");
    }
    for (const auto& [k, _] : g.poses) {
      if (graph::robot_of(k) >= robots) {
        std::fprintf(stderr, "cdc-peer-replay: the graph holds robot %u; --robots is %u\n",
                     static_cast<unsigned>(graph::robot_of(k)), robots);
        return 2;
      }
    }
    RadioTimeline radio;
    if (!links_path.empty()) radio.load(links_path);
    const auto stamp_of = [&](graph::Key k) {
      const uint64_t i = graph::index_of(k);
      const auto& s = stamps[graph::robot_of(k)];
      return i < s.size() ? s[i] : HUGE_VAL;
    };

    // Each robot's keyframes, their odometry chained from the graph's odometry factors.
    std::vector<std::map<uint32_t, peer::OwnKeyframe>> keyframes(robots);
    for (auto& k : keyframes) k[0] = peer::OwnKeyframe{};
    std::vector<const graph::Factor*> odometry;
    std::vector<TimedLoop> loops;
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> jitter(0.0, jitter_s);
    for (const graph::Factor& f : g.factors) {
      if (f.kind == graph::FactorKind::kOdometry) {
        odometry.push_back(&f);
      } else if (f.kind == graph::FactorKind::kLoop) {
        peer::LoopRecord l;
        l.sender = static_cast<uint32_t>(graph::robot_of(f.b));
        l.seq = static_cast<uint32_t>(loops.size());
        l.robot_a = static_cast<uint32_t>(graph::robot_of(f.a));
        l.keyframe_a = static_cast<uint32_t>(graph::index_of(f.a));
        l.robot_b = static_cast<uint32_t>(graph::robot_of(f.b));
        l.keyframe_b = static_cast<uint32_t>(graph::index_of(f.b));
        l.T_a_b = f.measurement;
        l.information = f.information;
        // An inter-robot loop is verified with the other robot's cloud: not before their link is up.
        const double t = std::max(stamp_of(f.a), stamp_of(f.b)) + latency_s + jitter(rng);
        loops.push_back({radio.next_up(l.robot_a, l.robot_b, t), l});
      }
    }
    std::sort(odometry.begin(), odometry.end(), [](const auto* a, const auto* b) { return a->b < b->b; });
    for (const graph::Factor* f : odometry) {
      auto& own = keyframes[graph::robot_of(f->a)];
      const auto id = static_cast<uint32_t>(graph::index_of(f->b));
      if (const auto prev = own.find(id - 1); id > 0 && prev != own.end()) {
        own[id] = peer::OwnKeyframe{id, 0, prev->second.T_odom * f->measurement, f->measurement, f->information};
      }
    }
    std::stable_sort(loops.begin(), loops.end(), [](const auto& a, const auto& b) { return a.available_s < b.available_s; });

    // The centralized problem the rounds should reach: the same loops, weighed as the peers weigh them.
    graph::PoseGraph central = g;
    if (base.share_loop_information) graph::share_loop_information(central);
    central.add_prior(graph::make_key(0, 0), keyframes[0].at(0).T_odom, graph::Matrix6d::Identity() * 1e6);

    std::vector<peer::PeerCore> cores;
    for (uint32_t r = 0; r < robots; ++r) {
      peer::PeerConfig c = base;
      c.robot = r;
      c.robot_count = robots;
      c.rtdos.range_m = 1e9;
      cores.emplace_back(c);
    }
    std::vector<uint32_t> next(robots, 0);
    size_t next_loop = 0;
    std::vector<Stamped> realtime(robots), odom(robots);
    std::vector<size_t> separator_poses(robots, 0);
    std::vector<std::vector<bool>> link_up(robots, std::vector<bool>(robots, true));
    std::vector<std::optional<peer::Correction>> last(robots);
    const auto joint_cost = [&] {
      graph::PoseGraph joint = central;
      for (uint32_t r = 0; r < robots; ++r) {
        if (last[r]) {
          for (const auto& [id, T] : last[r]->poses) joint.poses[graph::make_key(r, id)] = T;
        }
      }
      return graph::full_information_cost(joint);
    };
    double end_s = 0;
    for (const auto& s : stamps) end_s = std::max(end_s, s.empty() ? 0.0 : s.back());
    const long ticks = std::lround((end_s + tail_s) / 0.05);
    for (long tick = 0; tick <= ticks; ++tick) {
      const double t = static_cast<double>(tick) * 0.05;
      const peer::Nanos now{static_cast<int64_t>(tick) * 50'000'000};
      for (uint32_t r = 0; r < robots; ++r) {
        for (; next[r] < stamps[r].size() && stamps[r][next[r]] <= t && keyframes[r].count(next[r]) != 0; ++next[r]) {
          const peer::OwnKeyframe& k = keyframes[r].at(next[r]);
          cores[r].add_keyframe(k, now);
          odom[r].emplace_back(stamps[r][next[r]], k.T_odom.translation());
          // Where the front-end puts this keyframe: the newest corrected keyframe, as
          // T_world_robot^-1 * pose, carried on by the odometry.
          Eigen::Isometry3d T = k.T_odom;
          if (last[r] && !last[r]->poses.empty()) {
            const auto& [id, P] = last[r]->poses.back();
            T = last[r]->T_world_robot.inverse() * P * keyframes[r].at(id).T_odom.inverse() * k.T_odom;
          }
          realtime[r].emplace_back(stamps[r][next[r]], T.translation());
        }
      }
      for (; next_loop < loops.size() && loops[next_loop].available_s <= t; ++next_loop) {
        const peer::LoopRecord& l = loops[next_loop].record;
        cores[l.robot_a].add_loop(l, now);
        if (l.robot_b != l.robot_a) cores[l.robot_b].add_loop(l, now);
      }
      // A link back up: each end's reader matches anew, and the other end sends it every separator.
      for (uint32_t a = 0; a < robots; ++a) {
        for (uint32_t b = a + 1; b < robots; ++b) {
          const bool up = radio.up(a, b, t);
          if (up && !link_up[a][b]) {
            cores[a].resend_separators_to(b);
            cores[b].resend_separators_to(a);
          }
          link_up[a][b] = up;
        }
      }
      std::vector<peer::StepOutput> out;
      for (auto& c : cores) out.push_back(c.step(now, false));
      for (uint32_t r = 0; r < robots; ++r) {
        for (const auto& s : out[r].separators) {
          if (!radio.up(r, s.target, t)) continue;
          cores[s.target].on_separator(r, s.poses);
          separator_poses[r] += s.poses.size();
        }
        if (out[r].correction) last[r] = std::move(out[r].correction);
      }
      if (verbose && tick % 100 == 0) std::printf("t %.0f s: joint cost %.2f\n", t, joint_cost());
    }
    for (uint32_t r = 0; r < robots; ++r) {
      Stamped final_estimate;
      if (last[r]) {
        for (const auto& [id, P] : last[r]->poses) {
          if (id < stamps[r].size()) final_estimate.emplace_back(stamps[r][id], P.translation());
        }
      }
      std::printf("robot %u: %zu keyframes, %llu rounds, %zu separator poses sent; ATE odometry %.4f, real-time %.4f, final %.4f m\n", r,
                  odom[r].size(), static_cast<unsigned long long>(cores[r].distributed_rounds()), separator_poses[r],
                  ate_of(odom[r], truth[r]), ate_of(realtime[r], truth[r]), ate_of(final_estimate, truth[r]));
    }
    const double distributed = joint_cost();
    graph::SolverOptions o;
    o.robust_loss_scale = 0.0;  // as the rounds solve
    graph::solve(central, o);
    std::printf("joint cost: distributed %.2f, centralized optimum %.2f\n", distributed,
                graph::full_information_cost(central));
    if (graph_paths.size() > 1 && live.size() == g.poses.size()) {
      graph::PoseGraph run = central;
      for (const auto& [k, T] : live) run.poses[k] = T;
      std::printf("joint cost of the run's own estimate (each robot's keyframes from its graph): %.2f\n",
                  graph::full_information_cost(run));
      std::vector<Stamped> own(robots);
      for (const auto& [k, T] : live) own[graph::robot_of(k)].emplace_back(stamp_of(k), T.translation());
      for (uint32_t r = 0; r < robots; ++r) std::printf("robot %u: ATE of the run's own estimate %.4f m\n", r, ate_of(own[r], truth[r]));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cdc-peer-replay: %s\n", e.what());
    return 2;
  }
  return 0;
}
