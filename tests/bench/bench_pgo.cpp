// cdc-bench-pgo: pose-graph solve speed against a plain Ceres baseline, on one core.
// Baseline: Ceres' pose_graph_3d style (autodiff SE(3) residual, quaternion manifold, LM from the
// file's values, SPARSE_NORMAL_CHOLESKY, Ceres' default tolerances). Ours: chordal
// initialisation, then the same solve. Figure of merit: wall time until the cost is within a
// relative gap of 1e-4 of the best optimum either run reached (initialisation included), median
// over --runs. Last output line: one JSON object.
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <limits>

namespace {

using namespace cdc::graph;

struct Run {
  double init_s = 0;
  SolveResult solve;
};

Run run_once(const PoseGraph& input, bool chordal, Objective objective) {
  PoseGraph g = input;
  Run r;
  const auto t0 = std::chrono::steady_clock::now();
  if (chordal) {
    chordal_initialise(g);
  } else {
    initialise_from_odometry(g);  // only fills poses the file does not give
    for (const auto& [k, T] : input.poses) {
      g.poses[k] = T;
    }
  }
  r.init_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  SolverOptions o;
  o.objective = objective;
  o.max_iterations = 200;       // Ceres' pose_graph_3d example
  o.function_tolerance = 1e-6;  // Ceres' defaults
  o.gradient_tolerance = 1e-10;
  o.parameter_tolerance = 1e-8;
  // The baseline keeps Ceres' default initial trust region; ours starts nearly Gauss-Newton.
  o.initial_trust_region_radius = chordal ? SolverOptions{}.initial_trust_region_radius : 1e4;
  r.solve = solve(g, o);
  return r;
}

// Seconds until Ceres' cost is within `gap` of `best` (init time included); infinity if never.
double time_to_gap(const Run& r, double best, double gap) {
  for (const auto& [t, cost] : r.solve.trace) {
    if (cost <= best * (1.0 + gap)) {
      return r.init_s + t;
    }
  }
  return std::numeric_limits<double>::infinity();
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-bench-pgo: pose-graph solve speed against a plain Ceres baseline (one core)"};
  std::string data_dir;
  std::vector<std::string> graphs = {"3d/sphere2500.g2o", "3d/parking-garage.g2o"};
  int runs = 5;
  double gap = 1e-4;
  const char* env = std::getenv("CDC_DATA_DIR");
  data_dir = env != nullptr ? env : "../shared/data";
  app.add_option("--data", data_dir, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  app.add_option("--graph", graphs, "graphs under <data>/pose-graphs")->capture_default_str();
  app.add_option("--runs", runs, "runs per configuration (median reported)")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  app.add_option("--gap", gap, "relative gap that counts as reaching the optimum")->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  nlohmann::json out;
  for (const auto& name : graphs) {
    const std::string path = data_dir + "/pose-graphs/" + name;
    if (!std::filesystem::exists(path)) {
      std::cerr << "cdc-bench-pgo: " << path << " not found (set --data or CDC_DATA_DIR)\n";
      return 2;
    }
    const PoseGraph g = read_g2o(path);
    const std::string key = std::filesystem::path(name).stem().string();
    for (Objective obj : {Objective::kFullInformation, Objective::kSeSync}) {
      std::vector<Run> base, ours;
      for (int i = 0; i < runs; ++i) {
        base.push_back(run_once(g, false, obj));
        ours.push_back(run_once(g, true, obj));
      }
      double best = std::numeric_limits<double>::infinity();
      for (const auto* set : {&base, &ours}) {
        for (const Run& r : *set) {
          best = std::min(best, r.solve.trace.back().second);
        }
      }
      std::vector<double> tb, to, totb, toto;
      for (const Run& r : base) {
        tb.push_back(time_to_gap(r, best, gap));
        totb.push_back(r.init_s + r.solve.time_s);
      }
      for (const Run& r : ours) {
        to.push_back(time_to_gap(r, best, gap));
        toto.push_back(r.init_s + r.solve.time_s);
      }
      const std::string mode = obj == Objective::kSeSync ? "sesync" : "full";
      nlohmann::json j{{"baseline_time_to_gap_s", median(tb)},
                       {"ours_time_to_gap_s", median(to)},
                       {"speedup", median(tb) / median(to)},
                       {"baseline_total_s", median(totb)},
                       {"ours_total_s", median(toto)},
                       {"baseline_iterations", base.front().solve.iterations},
                       {"ours_iterations", ours.front().solve.iterations},
                       {"baseline_final_objective", 2.0 * base.front().solve.trace.back().second},
                       {"ours_final_objective", 2.0 * ours.front().solve.trace.back().second}};
      out[key][mode] = j;
      std::printf(
          "%-16s %-6s baseline %.3f s (%d it) | ours %.3f s (%d it) | to gap %.0e: %.3f s vs %.3f s, x%.2f | f %.6g vs "
          "%.6g\n",
          key.c_str(), mode.c_str(), median(totb), base.front().solve.iterations, median(toto),
          ours.front().solve.iterations, gap, median(tb), median(to), median(tb) / median(to),
          2.0 * base.front().solve.trace.back().second, 2.0 * ours.front().solve.trace.back().second);
    }
  }
  out["runs"] = runs;
  out["gap"] = gap;
  std::cout << out.dump() << '\n';
  return 0;
}
