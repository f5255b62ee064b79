// cdc-bench-gnc: robustness of the GNC back-end to wrong loop closures on the single-robot pose-graph
// benchmarks. Per graph: the clean graph's optimum (chordal start, full-information objective) is
// the reference; the odometry-only estimate (odometry chained, no loop) is the yardstick. For each
// count of wrong loops (random pairs of poses, random relative poses, seeded; their information a
// copy of a random true loop's), GNC solves the corrupted graph from the odometry-only estimate.
// Figure of merit: RMS translation error to the reference after SE(3) alignment, as a fraction of
// the odometry-only estimate's; the check holds at 5 %. The corrupted graphs are made in memory
// (--write-dir writes them for cdc-pgo). Last output line: one JSON object.
#include "cdc/geometry/metrics.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/solver.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

using namespace cdc::graph;
namespace geometry = cdc::geometry;

struct Benchmark {
  std::string name, file;
};

const std::vector<Benchmark> kBenchmarks = {{"intel", "2d/intel.g2o"},
                                            {"manhattan", "2d/manhattan.g2o"},
                                            {"sphere2500", "3d/sphere2500.g2o"},
                                            {"garage", "3d/parking-garage.g2o"}};

// Largest extent of the poses' positions along any axis [m].
double extent(const PoseGraph& g) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  for (const auto& [k, T] : g.poses) {
    lo = lo.cwiseMin(T.translation());
    hi = hi.cwiseMax(T.translation());
  }
  return (hi - lo).maxCoeff();
}

// Appends n wrong loops: two distinct poses that are not odometry neighbours, a relative pose with
// a translation uniform in a cube as large as the trajectory and a uniform rotation (yaw only for
// planar graphs), and the information of a random true loop.
void add_wrong_loops(PoseGraph& g, size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Key> keys;
  for (const auto& [k, T] : g.poses) keys.push_back(k);
  std::vector<Matrix6d> loop_info;
  for (const Factor& f : g.factors) {
    if (f.kind == FactorKind::kLoop) loop_info.push_back(f.information);
  }
  std::uniform_int_distribution<size_t> pick(0, keys.size() - 1), pick_info(0, loop_info.size() - 1);
  const double half = 0.5 * extent(g);
  std::uniform_real_distribution<double> u(-half, half), angle(-M_PI, M_PI);
  std::normal_distribution<double> normal;
  for (size_t added = 0; added < n;) {
    const Key a = keys[pick(rng)], b = keys[pick(rng)];
    if (robot_of(a) == robot_of(b) && (index_of(a) == index_of(b) || index_of(b) == index_of(a) + 1)) continue;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    if (g.dimension == 2) {
      T.translation() = Eigen::Vector3d(u(rng), u(rng), 0.0);
      T.linear() = Eigen::AngleAxisd(angle(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    } else {
      T.translation() = Eigen::Vector3d(u(rng), u(rng), u(rng));
      T.linear() =
          Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
    }
    g.add_between(a, b, T, loop_info[pick_info(rng)]);
    ++added;
  }
}

// The clean graph's poses from its odometry alone.
PoseGraph odometry_only(const PoseGraph& clean) {
  PoseGraph g = clean;
  std::erase_if(g.factors, [](const Factor& f) { return f.kind != FactorKind::kOdometry; });
  if (!initialise_from_odometry(g)) {
    throw std::runtime_error("the odometry does not connect every pose");
  }
  return g;
}

// RMS translation difference of two estimates of the same poses after SE(3) alignment [m].
double aligned_rmse(const PoseGraph& est, const PoseGraph& ref) {
  geometry::Poses e, r;
  for (const auto& [k, T] : ref.poses) {
    r.push_back(T);
    e.push_back(est.poses.at(k));
  }
  return geometry::compute_ate(e, r, geometry::AlignMode::kSE3).translation.rmse;
}

struct Setup {
  std::string data_dir, write_dir;
  std::vector<size_t> outliers = {10, 100, 500};
  uint64_t seed = 1;
  double bound = 0.05;
  GncOptions gnc;
};

// One corrupted graph of one benchmark, solved with GNC from the odometry-only estimate.
nlohmann::json run_case(const Benchmark& b, const PoseGraph& clean, const PoseGraph& reference,
                        const PoseGraph& odometry, size_t n, const Setup& s) {
  PoseGraph g = clean;
  add_wrong_loops(g, n, s.seed + n);
  if (!s.write_dir.empty()) {
    write_g2o(s.write_dir + "/" + b.name + "_" + std::to_string(n) + ".g2o", g);
  }
  g.poses = odometry.poses;
  SolverOptions o;
  o.gnc = s.gnc;
  o.gnc.enabled = true;
  const SolveResult r = solve(g, o);
  size_t wrong_accepted = 0, true_rejected = 0;
  for (size_t i = 0; i < g.factors.size(); ++i) {
    if (g.factors[i].kind != FactorKind::kLoop) continue;
    const bool accepted = r.weights[i] > kGncAcceptedWeight;
    wrong_accepted += i >= clean.factors.size() && accepted ? 1u : 0u;
    true_rejected += i < clean.factors.size() && !accepted ? 1u : 0u;
  }
  const double rmse = aligned_rmse(g, reference), odo = aligned_rmse(odometry, reference);
  const double ratio = rmse / odo;
  std::printf(
      "%-10s %4zu wrong loops: RMS %.4g m = %.3f %% of odometry-only (%.4g m); %zu wrong accepted, %zu "
      "true rejected; c^2 %.3g, %d rounds, %d iterations, %.2f s\n",
      b.name.c_str(), n, rmse, 100.0 * ratio, odo, wrong_accepted, true_rejected, r.gnc_threshold, r.gnc_rounds,
      r.iterations, r.time_s);
  return {{"benchmark", b.name},
          {"wrong_loops", n},
          {"rmse_m", rmse},
          {"odometry_rmse_m", odo},
          {"ratio", ratio},
          {"pass", ratio <= s.bound},
          {"wrong_accepted", wrong_accepted},
          {"true_loops", clean.count(FactorKind::kLoop)},
          {"true_rejected", true_rejected},
          {"gnc_rounds", r.gnc_rounds},
          {"gnc_threshold", r.gnc_threshold},
          {"gnc_converged", r.gnc_converged},
          {"iterations", r.iterations},
          {"solve_time_s", r.time_s}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-bench-gnc: GNC against random wrong loop closures on the pose-graph benchmarks"};
  Setup s;
  const char* env = std::getenv("CDC_DATA_DIR");
  s.data_dir = env != nullptr ? env : "../shared/data";
  std::vector<std::string> only;
  app.add_option("--data", s.data_dir, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  app.add_option("--benchmark", only, "benchmarks to run (intel, manhattan, sphere2500, garage; default all)");
  app.add_option("--outliers", s.outliers, "counts of wrong loops added")->capture_default_str();
  app.add_option("--seed", s.seed, "random seed (each count uses seed + count)")->capture_default_str();
  app.add_option("--threshold", s.gnc.inlier_threshold, "GNC inlier threshold c^2")->capture_default_str();
  app.add_option("--mu-step", s.gnc.mu_step, "GNC mu growth per round")->capture_default_str();
  app.add_flag("--calibrate", s.gnc.calibrate_threshold, "scale the threshold by the accepted loops' residuals");
  app.add_flag("--least-squares-start", s.gnc.least_squares_start, "start GNC from the least-squares solution");
  app.add_option("--bound", s.bound, "largest passing ratio to the odometry-only error")->capture_default_str();
  app.add_option("--write-dir", s.write_dir, "write each corrupted graph (g2o) into this folder");
  CLI11_PARSE(app, argc, argv);

  nlohmann::json cases = nlohmann::json::array();
  bool pass = true;
  for (const Benchmark& b : kBenchmarks) {
    if (!only.empty() && std::find(only.begin(), only.end(), b.name) == only.end()) continue;
    const std::string path = s.data_dir + "/pose-graphs/" + b.file;
    if (!std::filesystem::exists(path)) {
      std::cerr << "cdc-bench-gnc: " << path << " not found (set --data or CDC_DATA_DIR)\n";
      return 2;
    }
    PoseGraph clean = read_g2o(path);
    const PoseGraph odometry = odometry_only(clean);
    clean.poses = odometry.poses;
    PoseGraph reference = clean;
    chordal_initialise(reference);
    solve(reference, SolverOptions{});
    for (size_t n : s.outliers) {
      cases.push_back(run_case(b, clean, reference, odometry, n, s));
      pass = pass && cases.back()["pass"].get<bool>();
    }
  }
  std::cout << nlohmann::json{{"cases", cases}, {"bound", s.bound}, {"seed", s.seed}, {"pass", pass}}.dump() << '\n';
  return pass ? 0 : 1;
}
