// cdc-pgo: solve a pose graph from g2o files, centralized or distributed over robots.
#include "cdc/base/cli.hpp"
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/graph/distributed.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <stdexcept>

namespace {

namespace graph = cdc::graph;
using Clock = std::chrono::steady_clock;

struct Options {
  std::string input, out_path, init;  // init empty: chordal, or odometry with --robust gnc
  std::string robust = "none";
  double robust_scale = 3.0;
  double gnc_threshold = graph::GncOptions{}.inlier_threshold;
  bool gnc_calibrate = false;
  bool json = false, sesync_weights = false, verbose = false, distributed = false, share_loops = false;
  bool parallel = false;
  int max_rounds = 30;
  std::string method = "two-stage";
  double tilt_scale = 1.0;
  double over_relaxation = graph::DistributedOptions{}.over_relaxation;
  int max_iterations = 100;
  double tolerance = 1e-10;
  double trust_region = 1e12;
  std::string backend = "suitesparse";
};

void add_options(CLI::App& app, Options& o) {
  cdc::base::add_input(app, "input", o.input, "a .g2o file, or a folder of per-robot .g2o files", CLI::ExistingPath);
  app.add_option("--init", o.init,
                 "initial values: chordal (rotation relaxation), odometry (chained; with --robust gnc the odometry "
                 "alone), file (VERTEX lines; a file without them falls back to odometry); default chordal, "
                 "odometry with --robust gnc")
      ->check(CLI::IsMember({"chordal", "odometry", "file"}));
  cdc::base::add_setting(app, "--robust", o.robust,
                         "loss on loop closures: none (least squares), cauchy (Cauchy loss of --robust-scale), gnc "
                         "(graduated non-convexity, truncated least squares; odometry stays quadratic)",
                         CLI::IsMember({"none", "cauchy", "gnc"}));
  cdc::base::add_setting(app, "--robust-scale", o.robust_scale, "--robust cauchy: the loss's scale",
                         cdc::config::cli_range(1e-6, 1e6));
  cdc::base::add_setting(app, "--gnc-threshold", o.gnc_threshold,
                         "--robust gnc: squared weighted residual r^T Omega r above which a loop is an outlier",
                         cdc::config::cli_range(1e-6, 1e12));
  app.add_flag("--gnc-calibrate", o.gnc_calibrate,
               "--robust gnc: when the accepted loops fit far better than their information says, lower the "
               "threshold to 100 times their median squared residual and run GNC again");
  app.add_flag("--sesync-weights", o.sesync_weights,
               "optimise SE-Sync's isotropic chordal objective instead of the full-information cost");
  app.add_flag("--share-loops", o.share_loops,
               "divide each loop closure's information by the most loops either of its keyframes takes part in"
               " (as the optimiser services do; --out then writes the divided information)");
  cdc::base::add_setting(
      app, "--loop-tilt-scale", o.tilt_scale,
      "scale each loop closure's roll/pitch information by this factor in its keyframe's level frame"
      " (world z up, from the estimate read), as the loop-closure service does for robots whose odometry"
      " holds its tilt with gravity; for graphs whose loops were not levelled",
      cdc::config::cli_range(0, 1));
  cdc::base::add_setting(app, "--max-iterations", o.max_iterations, "solver iteration limit",
                         cdc::config::cli_range(1, 1e6));
  cdc::base::add_setting(app, "--tolerance", o.tolerance, "relative cost-change tolerance at which the solver stops",
                         cdc::config::cli_range(1e-16, 1));
  cdc::base::add_setting(app, "--trust-region", o.trust_region, "initial trust-region radius (1 / initial LM damping)",
                         cdc::config::cli_range(1e-12, 1e16));
  cdc::base::add_setting(app, "--sparse-backend", o.backend, "sparse Cholesky library",
                         CLI::IsMember({"suitesparse", "eigen", "cxsparse"}));
  app.add_option("--out", o.out_path, "write the optimised graph to this .g2o file");
  app.add_flag("--json", o.json, "print one JSON line instead of text");
  app.add_flag("--distributed", o.distributed,
               "also run the distributed algorithm (robots = top byte of the keys; exchanges separator poses only)"
               " and compare it with the centralized solution");
  cdc::base::add_setting(app, "--distributed-method", o.method,
                         "distributed: two-stage (rotations, then translations, then poses; each robot starts from"
                         " its own chordal estimate) or block-gs (block Gauss-Seidel on poses from a rigid placement"
                         " of the robots)",
                         CLI::IsMember({"two-stage", "block-gs"}));
  app.add_flag("--parallel", o.parallel,
               "distributed two-stage: all robots update at once from the previous round's estimates (block Jacobi)"
               " instead of one after the other");
  cdc::base::add_setting(app, "--over-relaxation", o.over_relaxation,
                         "distributed block-gs: over-relaxation factor gamma (1 = Gauss-Seidel)",
                         cdc::config::cli_range(0.1, 1.99));
  cdc::base::add_setting(app, "--max-rounds", o.max_rounds, "distributed: round limit", cdc::config::cli_range(1, 1e6));
  app.add_flag("--verbose", o.verbose, "print the solver's full report to stderr");
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// With SE-Sync's weights only tau and kappa of each information matter: they must be positive, the
// full 6x6 need not be positive definite.
graph::PoseGraph read_graph(const std::string& input, bool isotropic_information,
                            graph::G2oReadReport* report = nullptr) {
  graph::G2oReadOptions options;
  options.report = report;
  options.isotropic_information = isotropic_information;
  return std::filesystem::is_directory(input) ? graph::read_g2o_folder(input, options)
                                              : graph::read_g2o(input, options);
}

// Says what the read found about vertices that are not plainly declared once.
void note_vertices(const std::string& input, const graph::G2oReadReport& r) {
  if (r.implicit_vertices > 0) {
    std::fprintf(stderr, "cdc-pgo: %s declares no VERTEX lines: all %zu poses are initialised from the edges\n",
                 input.c_str(), r.implicit_vertices);
  }
  if (r.parallel_edges > 0) {
    std::fprintf(stderr, "cdc-pgo: %s: %zu edges link two poses another edge already links; each is a factor\n",
                 input.c_str(), r.parallel_edges);
  }
  if (r.conflicting_vertices > 0) {
    std::fprintf(stderr,
                 "cdc-pgo: %s: %zu vertices are declared by several files with different poses; the first "
                 "file's are used\n",
                 input.c_str(), r.conflicting_vertices);
  }
}

bool has_missing_vertices(const graph::PoseGraph& g) {
  for (const auto& f : g.factors) {
    if (g.poses.count(f.a) == 0 || g.poses.count(f.b) == 0) {
      return true;
    }
  }
  return false;
}

// The initialisation --init asks for (or its default) and the one that runs.
struct InitChoice {
  std::string requested, used;
  std::string note;  // why `used` differs from `requested`; empty when it does not
};

InitChoice choose_init(const graph::PoseGraph& g, const Options& o) {
  InitChoice c;
  c.requested = !o.init.empty() ? o.init : o.robust == "gnc" ? "odometry" : "chordal";
  c.used = c.requested;
  if (c.requested == "file" && has_missing_vertices(g)) {
    c.used = "odometry";
    c.note = "the input declares no vertices, so odometry is chained instead";
  }
  return c;
}

// Chains the odometry factors alone (GNC's start: wrong loops place nothing).
bool initialise_from_odometry_alone(graph::PoseGraph& g) {
  graph::PoseGraph odometry = g;
  std::erase_if(odometry.factors, [](const graph::Factor& f) { return f.kind != graph::FactorKind::kOdometry; });
  const bool connected = graph::initialise_from_odometry(odometry);
  g.poses = odometry.poses;
  return connected && g.poses.size() == odometry.poses.size() && !has_missing_vertices(g);
}

void initialise(graph::PoseGraph& g, const Options& o, const InitChoice& c) {
  bool connected = true;
  if (c.used == "chordal") {
    connected = graph::chordal_initialise(g);
  } else if (c.used == "odometry") {
    connected = o.robust == "gnc" ? initialise_from_odometry_alone(g) : graph::initialise_from_odometry(g);
  }
  if (!connected) {
    throw std::runtime_error(o.input + ": the graph is not connected" +
                             (o.robust == "gnc" && c.used == "odometry"
                                  ? std::string(" by its odometry alone (--robust gnc chains odometry only; use "
                                                "--init chordal or file)")
                                  : std::string("; only the anchor's component is solved")));
  }
}

graph::SolverOptions solver_options(const Options& o) {
  graph::SolverOptions opts;
  opts.max_iterations = o.max_iterations;
  opts.function_tolerance = o.tolerance;
  opts.initial_trust_region_radius = o.trust_region;
  opts.sparse_backend = o.backend == "eigen"      ? graph::SparseBackend::kEigen
                        : o.backend == "cxsparse" ? graph::SparseBackend::kCxSparse
                                                  : graph::SparseBackend::kSuiteSparse;
  opts.objective = o.sesync_weights ? graph::Objective::kSeSync : graph::Objective::kFullInformation;
  opts.full_report = o.verbose;
  if (o.robust == "cauchy") opts.robust_loss_scale = o.robust_scale;
  opts.gnc.enabled = o.robust == "gnc";
  opts.gnc.inlier_threshold = o.gnc_threshold;
  opts.gnc.calibrate_threshold = o.gnc_calibrate;
  return opts;
}

void print_report(const graph::SolveResult& r) {
  std::cerr << r.report << "\niteration  time_s  objective\n";
  for (size_t i = 0; i < r.trace.size(); ++i) {
    std::fprintf(stderr, "%9zu  %6.3f  %.10g\n", i, r.trace[i].first, 2.0 * r.trace[i].second);
  }
}

// The first round whose objective is within 1 % of the centralized one; -1 if none is.
int rounds_to_1pct(const graph::DistributedResult& r, double f_central) {
  for (size_t i = 0; i < r.objective_per_round.size(); ++i) {
    if (r.objective_per_round[i] <= 1.01 * f_central) {
      return r.objective_first_round + static_cast<int>(i);
    }
  }
  return -1;
}

// Position and rotation deviations of the same keys between two graphs: RMS and largest [m], largest [rad].
struct Deviation {
  double rms_m = 0, max_m = 0, max_rad = 0;
};

Deviation deviation(const graph::PoseGraph& reference, const graph::PoseGraph& other) {
  Deviation d;
  for (const auto& [k, T] : reference.poses) {
    const Eigen::Isometry3d& U = other.poses.at(k);
    const double e = (U.translation() - T.translation()).norm();
    d.rms_m += e * e;
    d.max_m = std::max(d.max_m, e);
    d.max_rad = std::max(d.max_rad, Eigen::AngleAxisd(T.rotation().transpose() * U.rotation()).angle());
  }
  d.rms_m = std::sqrt(d.rms_m / static_cast<double>(reference.poses.size()));
  return d;
}

// Bytes each robot sent, initialisation and rounds together, keyed by the robot's number as text.
nlohmann::json bytes_per_robot(const graph::DistributedResult& init, graph::DistributedResult& rounds) {
  nlohmann::json bytes;
  for (const auto& [robot, b] : init.bytes_sent) {
    bytes[std::to_string(robot)] = b + rounds.bytes_sent[robot];
  }
  for (const auto& [robot, b] : rounds.bytes_sent) {
    if (!bytes.contains(std::to_string(robot))) {
      bytes[std::to_string(robot)] = b;
    }
  }
  return bytes;
}

// Time each robot spent on its own solves [s], keyed by the robot's number as text (two-stage only).
nlohmann::json compute_per_robot(const graph::DistributedResult& r) {
  nlohmann::json out = nlohmann::json::object();
  for (const auto& [robot, s] : r.compute_s) {
    out[std::to_string(robot)] = s;
  }
  return out;
}

// Runs the distributed algorithm --distributed-method names on the graph as read.
graph::DistributedResult solve_distributed(const Options& o, const graph::SolverOptions& local,
                                           graph::PoseGraph& solution, graph::DistributedResult& init) {
  graph::DistributedOptions dopts;
  dopts.max_rounds = o.max_rounds;
  dopts.local = local;
  dopts.over_relaxation = o.over_relaxation;
  dopts.two_stage.parallel = o.parallel;
  if (o.method == "two-stage") {
    return graph::solve_distributed_two_stage(solution, dopts);
  }
  if (!graph::initialise_distributed(solution, &init)) {
    throw std::runtime_error(o.input + ": some robot shares no inter-robot factor with the others");
  }
  return graph::solve_distributed(solution, dopts);
}

// Runs the distributed algorithm from the input file and compares it with the centralized solution
// `central` (objective f_central); returns its figures and leaves its solution in `solution`.
nlohmann::json run_distributed(const Options& o, const graph::SolverOptions& local, const graph::PoseGraph& central,
                               double f_central, graph::PoseGraph& solution) {
  solution = read_graph(o.input, o.sesync_weights);
  graph::DistributedResult init;
  const auto d0 = Clock::now();
  graph::DistributedResult dr = solve_distributed(o, local, solution, init);
  const double dist_s = seconds_since(d0);
  const double f_dist = dr.objective_per_round.back();
  const Deviation dev = deviation(central, solution);
  const nlohmann::json bytes = bytes_per_robot(init, dr);
  nlohmann::json per_round;
  for (const auto& [robot, b] : bytes.items()) {
    per_round[robot] = static_cast<double>(b.get<uint64_t>()) / std::max(dr.rounds, 1);
  }
  return {{"distributed_method", o.method},
          {"rounds", dr.rounds},
          {"rotation_rounds", dr.rotation_rounds},
          {"translation_rounds", dr.translation_rounds},
          {"distributed_converged", dr.converged},
          {"rounds_to_1pct", rounds_to_1pct(dr, f_central)},
          {"distributed_objective", f_dist},
          {"centralized_objective", f_central},
          {"gap_to_centralized", (f_dist - f_central) / f_central},
          {"ate_to_centralized_m", dev.rms_m},
          {"max_deviation_m", dev.max_m},
          {"max_rotation_deviation_rad", dev.max_rad},
          {"bytes_per_robot", bytes},
          {"bytes_per_robot_per_round", per_round},
          {"bytes_per_round", dr.bytes_per_round},
          {"compute_s_per_robot", compute_per_robot(dr)},
          {"objective_per_round", dr.objective_per_round},
          {"distributed_time_s", dist_s}};
}

// What the run found, as the JSON line and the text both show it.
struct Summary {
  graph::SolveResult solve;
  InitChoice init;
  double init_s = 0, total_s = 0;
  double initial_full = 0, initial_sesync = 0;  // the costs at the initial values
  double full = 0, sesync = 0;                  // the centralized solution's costs
  nlohmann::json distributed;                   // empty without --distributed
  graph::G2oReadReport read;                    // what the read found about the vertices
};

// GNC's figures: its rounds and how many loops it kept.
nlohmann::json gnc_json(const graph::PoseGraph& g, const graph::SolveResult& r) {
  size_t loops = 0, accepted = 0;
  for (size_t i = 0; i < g.factors.size(); ++i) {
    if (g.factors[i].robust) {
      ++loops;
      accepted += r.weights[i] > graph::kGncAcceptedWeight ? 1u : 0u;
    }
  }
  return {{"gnc_rounds", r.gnc_rounds},       {"gnc_threshold", r.gnc_threshold},
          {"gnc_converged", r.gnc_converged}, {"loops", loops},
          {"loops_accepted", accepted},       {"loops_rejected", loops - accepted}};
}

// The full-information cost, or null where some information is not positive definite (read for
// SE-Sync's weights only): a sum of indefinite quadratic forms is no cost.
nlohmann::json full_cost(const graph::G2oReadReport& read, double cost) {
  return read.indefinite_information > 0 ? nlohmann::json(nullptr) : nlohmann::json(cost);
}

void print_json(const Options& o, const graph::PoseGraph& g, const Summary& s) {
  nlohmann::json j{{"file", o.input},
                   {"poses", g.poses.size()},
                   {"factors", g.factors.size()},
                   {"implicit_vertices", s.read.implicit_vertices},
                   {"conflicting_vertices", s.read.conflicting_vertices},
                   {"duplicate_edges", s.read.duplicate_edges},
                   {"parallel_edges", s.read.parallel_edges},
                   {"indefinite_information", s.read.indefinite_information},
                   {"init", s.init.used},
                   {"init_requested", s.init.requested},
                   {"objective", o.sesync_weights ? "sesync" : "full_information"},
                   {"robust", o.robust},
                   {"iterations", s.solve.iterations},
                   {"converged", s.solve.converged},
                   {"init_time_s", s.init_s},
                   {"solve_time_s", s.solve.time_s},
                   {"time_s", s.total_s},
                   {"initial_cost", full_cost(s.read, s.initial_full)},
                   {"initial_sesync_objective", s.initial_sesync},
                   {"cost", full_cost(s.read, s.full)},
                   {"sesync_objective", s.sesync}};
  if (!s.init.note.empty()) j["init_note"] = s.init.note;
  if (o.robust == "cauchy") j["robust_scale"] = o.robust_scale;
  if (o.robust == "gnc") j.update(gnc_json(g, s.solve));
  if (o.distributed) {
    j.update(s.distributed);
  }
  std::cout << j.dump() << '\n';
}

void print_distributed_text(const nlohmann::json& d) {
  std::printf(
      "distributed      %s, %d rounds (%d rotation, %d translation; 1%% of centralized after %d), objective "
      "%.6g, gap %.2e, deviation from centralized RMS %.4g m, largest %.4g m, %.3g rad, %.3f s\n",
      d["distributed_method"].get<std::string>().c_str(), d["rounds"].get<int>(), d["rotation_rounds"].get<int>(),
      d["translation_rounds"].get<int>(), d["rounds_to_1pct"].get<int>(), d["distributed_objective"].get<double>(),
      d["gap_to_centralized"].get<double>(), d["ate_to_centralized_m"].get<double>(),
      d["max_deviation_m"].get<double>(), d["max_rotation_deviation_rad"].get<double>(),
      d["distributed_time_s"].get<double>());
  for (const auto& [robot, b] : d["bytes_per_robot"].items()) {
    std::printf("  robot %s sent %llu bytes (%.0f per round)\n", robot.c_str(),
                static_cast<unsigned long long>(b.get<uint64_t>()),
                d["bytes_per_robot_per_round"][robot].get<double>());
  }
}

void print_text(const Options& o, const graph::PoseGraph& g, const Summary& s) {
  std::printf("%s: %zu poses, %zu factors (init %s, objective %s, robust %s)\n", o.input.c_str(), g.poses.size(),
              g.factors.size(), s.init.used.c_str(), o.sesync_weights ? "SE-Sync" : "full information",
              o.robust.c_str());
  if (!s.init.note.empty()) {
    std::printf("init             %s (--init %s: %s)\n", s.init.used.c_str(), s.init.requested.c_str(),
                s.init.note.c_str());
  }
  std::printf("iterations       %d (%s)\n", s.solve.iterations, s.solve.message.c_str());
  std::printf("time             %.3f s (init %.3f s, solve %.3f s)\n", s.total_s, s.init_s, s.solve.time_s);
  if (s.read.indefinite_information > 0) {
    std::printf("cost             none (%zu edges' information is not positive definite)\n",
                s.read.indefinite_information);
  } else {
    std::printf("cost             %.6g (full information, no 1/2)\n", s.full);
  }
  std::printf("sesync_objective %.6g\n", s.sesync);
  if (o.robust == "gnc") {
    const nlohmann::json j = gnc_json(g, s.solve);
    std::printf("gnc              %d rounds (%s), %zu of %zu loops accepted\n", j["gnc_rounds"].get<int>(),
                j["gnc_converged"].get<bool>() ? "weights settled" : "weights not settled",
                j["loops_accepted"].get<size_t>(), j["loops"].get<size_t>());
  }
  if (o.distributed) {
    print_distributed_text(s.distributed);
  }
}

// Reads, initialises and solves the graph (and the distributed algorithm when asked), writes --out
// and prints the figures.
void run(const Options& o) {
  graph::G2oReadReport read;
  graph::PoseGraph g = read_graph(o.input, o.sesync_weights, &read);
  note_vertices(o.input, read);
  if (o.share_loops) {
    graph::share_loop_information(g);
  }
  graph::level_loop_information(g, o.tilt_scale);
  Summary s;
  s.read = read;
  const auto t0 = Clock::now();
  s.init = choose_init(g, o);
  if (!s.init.note.empty()) {
    std::fprintf(stderr, "cdc-pgo: --init %s: %s\n", s.init.requested.c_str(), s.init.note.c_str());
  }
  initialise(g, o, s.init);
  s.init_s = seconds_since(t0);
  s.initial_full = graph::full_information_cost(g);
  s.initial_sesync = graph::sesync_objective(g);
  const graph::SolverOptions opts = solver_options(o);
  s.solve = graph::solve(g, opts);
  if (o.verbose) {
    print_report(s.solve);
  }
  if (s.solve.failed) {
    throw std::runtime_error(o.input + ": the solver failed (" + s.solve.message + "); nothing written");
  }
  s.total_s = seconds_since(t0);
  s.full = graph::full_information_cost(g);
  s.sesync = graph::sesync_objective(g);
  if (o.distributed) {
    graph::PoseGraph solution;
    s.distributed = run_distributed(o, opts, g, o.sesync_weights ? s.sesync : s.full, solution);
    g = std::move(solution);  // --out writes the distributed solution
  }
  if (!o.out_path.empty()) {
    graph::write_g2o(o.out_path, g);
  }
  if (o.json) {
    print_json(o, g, s);
  } else {
    print_text(o, g, s);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-pgo: optimise a pose graph (g2o: VERTEX_SE3:QUAT/EDGE_SE3:QUAT, or SE2 lifted into 3D).\n"
      "Prints iterations, time, final cost (full information, no 1/2) and SE-Sync's objective f."};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  return cdc::base::run_tool("cdc-pgo", [&] {
    run(o);
    return 0;
  });
}
