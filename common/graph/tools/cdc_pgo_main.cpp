// cdc-pgo: solve a pose graph from g2o files, centralized or distributed over robots.
#include "cdc/graph/distributed.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-pgo: optimise a pose graph (g2o: VERTEX_SE3:QUAT/EDGE_SE3:QUAT, or SE2 lifted into 3D).\n"
      "Prints iterations, time, final cost (full information, no 1/2) and SE-Sync's objective f."};
  std::string input, out_path, init = "chordal";
  bool json = false, sesync_weights = false, verbose = false, distributed = false, share_loops = false;
  int max_rounds = 30;
  double tilt_scale = 1.0;
  double sor = cdc::graph::DistributedOptions{}.over_relaxation;
  int max_iterations = 100;
  double tolerance = 1e-10;
  double radius = 1e12;
  std::string backend = "suitesparse";
  app.add_option("input", input, "a .g2o file, or a folder of per-robot .g2o files")->required()->check(CLI::ExistingPath);
  app.add_option("--init", init, "initial values: chordal (rotation relaxation), odometry (chained), file (VERTEX lines)")
      ->check(CLI::IsMember({"chordal", "odometry", "file"}))
      ->capture_default_str();
  app.add_flag("--sesync-weights", sesync_weights,
               "optimise SE-Sync's isotropic chordal objective instead of the full-information cost");
  app.add_flag("--share-loops", share_loops,
               "divide each loop closure's information by the most loops either of its keyframes takes part in"
               " (as the optimiser services do; --out then writes the divided information)");
  app.add_option("--loop-tilt-scale", tilt_scale,
                 "scale each loop closure's roll/pitch information by this factor in its keyframe's level frame"
                 " (world z up, from the estimate read), as the loop-closure service does for robots whose odometry"
                 " holds its tilt with gravity; for graphs whose loops were not levelled")
      ->check(CLI::Range(0.0, 1.0))->capture_default_str();
  app.add_option("--max-iterations", max_iterations, "solver iteration limit")->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_option("--tolerance", tolerance, "relative cost-change tolerance at which the solver stops")
      ->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--trust-region", radius, "initial trust-region radius (1 / initial LM damping)")
      ->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--sparse-backend", backend, "sparse Cholesky library")
      ->check(CLI::IsMember({"suitesparse", "eigen", "cxsparse"}))->capture_default_str();
  app.add_option("--out", out_path, "write the optimised graph to this .g2o file");
  app.add_flag("--json", json, "print one JSON line instead of text");
  app.add_flag("--distributed", distributed,
               "also run the distributed algorithm (robots = top byte of the keys; exchanges separator poses only)"
               " and compare it with the centralized solution");
  app.add_option("--over-relaxation", sor, "distributed: over-relaxation factor gamma (1 = Gauss-Seidel)")
      ->check(CLI::Range(0.1, 1.99))->capture_default_str();
  app.add_option("--max-rounds", max_rounds, "distributed: round limit")->check(CLI::PositiveNumber)
      ->capture_default_str();
  app.add_flag("--verbose", verbose, "print the solver's full report to stderr");
  CLI11_PARSE(app, argc, argv);

  try {
    cdc::graph::PoseGraph graph = std::filesystem::is_directory(input) ? cdc::graph::read_g2o_folder(input)
                                                                        : cdc::graph::read_g2o(input);
    if (share_loops) {
      cdc::graph::share_loop_information(graph);
    }
    cdc::graph::level_loop_information(graph, tilt_scale);
    const auto t0 = std::chrono::steady_clock::now();
    bool missing_vertices = false;
    for (const auto& f : graph.factors) {
      if (graph.poses.count(f.a) == 0 || graph.poses.count(f.b) == 0) {
        missing_vertices = true;
        break;
      }
    }
    bool connected = true;
    if (init == "chordal") {
      connected = cdc::graph::chordal_initialise(graph);
    } else if (init == "odometry" || missing_vertices) {
      connected = cdc::graph::initialise_from_odometry(graph);
    }
    if (!connected) {
      std::cerr << "cdc-pgo: " << input << ": the graph is not connected; only the anchor's component is solved\n";
      return 1;
    }
    const double init_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    cdc::graph::SolverOptions opts;
    opts.max_iterations = max_iterations;
    opts.function_tolerance = tolerance;
    opts.initial_trust_region_radius = radius;
    opts.sparse_backend = backend == "eigen"     ? cdc::graph::SparseBackend::kEigen
                          : backend == "cxsparse" ? cdc::graph::SparseBackend::kCxSparse
                                                  : cdc::graph::SparseBackend::kSuiteSparse;
    opts.objective = sesync_weights ? cdc::graph::Objective::kSeSync : cdc::graph::Objective::kFullInformation;
    opts.full_report = verbose;
    const cdc::graph::SolveResult r = cdc::graph::solve(graph, opts);
    if (verbose) {
      std::cerr << r.report << "\niteration  time_s  objective\n";
      for (size_t i = 0; i < r.trace.size(); ++i) {
        std::fprintf(stderr, "%9zu  %6.3f  %.10g\n", i, r.trace[i].first, 2.0 * r.trace[i].second);
      }
    }
    const double total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const double full = cdc::graph::full_information_cost(graph);
    const double sesync = cdc::graph::sesync_objective(graph);
    nlohmann::json dist_json;
    if (distributed) {
      cdc::graph::PoseGraph dgraph = std::filesystem::is_directory(input) ? cdc::graph::read_g2o_folder(input)
                                                                           : cdc::graph::read_g2o(input);
      cdc::graph::DistributedResult acc;
      const auto d0 = std::chrono::steady_clock::now();
      if (!cdc::graph::initialise_distributed(dgraph, &acc)) {
        std::cerr << "cdc-pgo: " << input << ": some robot shares no inter-robot factor with the others\n";
        return 1;
      }
      cdc::graph::DistributedOptions dopts;
      dopts.max_rounds = max_rounds;
      dopts.local = opts;
      dopts.over_relaxation = sor;
      cdc::graph::DistributedResult dr = cdc::graph::solve_distributed(dgraph, dopts);
      const double dist_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - d0).count();
      const double f_central = sesync_weights ? sesync : full;
      const double f_dist = dr.objective_per_round.back();
      int rounds_to_1pct = -1;
      for (size_t i = 0; i < dr.objective_per_round.size(); ++i) {
        if (dr.objective_per_round[i] <= 1.01 * f_central) {
          rounds_to_1pct = static_cast<int>(i);
          break;
        }
      }
      double se = 0.0;
      for (const auto& [k, T] : graph.poses) {
        se += (dgraph.poses.at(k).translation() - T.translation()).squaredNorm();
      }
      const double ate = std::sqrt(se / static_cast<double>(graph.poses.size()));
      nlohmann::json bytes;
      for (const auto& [robot, b] : acc.bytes_sent) {
        bytes[std::to_string(robot)] = b + dr.bytes_sent[robot];
      }
      for (const auto& [robot, b] : dr.bytes_sent) {
        if (!bytes.contains(std::to_string(robot))) {
          bytes[std::to_string(robot)] = b;
        }
      }
      dist_json = {{"rounds", dr.rounds},
                   {"converged", dr.converged},
                   {"rounds_to_1pct", rounds_to_1pct},
                   {"distributed_objective", f_dist},
                   {"centralized_objective", f_central},
                   {"gap_to_centralized", (f_dist - f_central) / f_central},
                   {"ate_to_centralized_m", ate},
                   {"bytes_per_robot", bytes},
                   {"objective_per_round", dr.objective_per_round},
                   {"distributed_time_s", dist_s}};
      graph = dgraph;  // --out writes the distributed solution
    }
    if (!out_path.empty()) {
      cdc::graph::write_g2o(out_path, graph);
    }
    if (json) {
      nlohmann::json j{{"file", input},
                       {"poses", graph.poses.size()},
                       {"factors", graph.factors.size()},
                       {"init", init},
                       {"objective", sesync_weights ? "sesync" : "full_information"},
                       {"iterations", r.iterations},
                       {"converged", r.converged},
                       {"init_time_s", init_s},
                       {"solve_time_s", r.time_s},
                       {"time_s", total_s},
                       {"initial_cost", r.initial_cost},
                       {"cost", full},
                       {"sesync_objective", sesync}};
      if (distributed) {
        j.update(dist_json);
      }
      std::cout << j.dump() << '\n';
    } else {
      std::printf("%s: %zu poses, %zu factors (init %s, objective %s)\n", input.c_str(), graph.poses.size(),
                  graph.factors.size(), init.c_str(), sesync_weights ? "SE-Sync" : "full information");
      std::printf("iterations       %d (%s)\n", r.iterations, r.message.c_str());
      std::printf("time             %.3f s (init %.3f s, solve %.3f s)\n", total_s, init_s, r.time_s);
      std::printf("cost             %.6g (full information, no 1/2)\n", full);
      std::printf("sesync_objective %.6g\n", sesync);
      if (distributed) {
        std::printf("distributed      %d rounds (1%% of centralized after %d), objective %.6g, gap %.2e, ATE to "
                    "centralized %.4g m\n",
                    dist_json["rounds"].get<int>(), dist_json["rounds_to_1pct"].get<int>(),
                    dist_json["distributed_objective"].get<double>(), dist_json["gap_to_centralized"].get<double>(),
                    dist_json["ate_to_centralized_m"].get<double>());
        for (const auto& [robot, b] : dist_json["bytes_per_robot"].items()) {
          std::printf("  robot %s sent %llu bytes of separator poses\n", robot.c_str(),
                      static_cast<unsigned long long>(b.get<uint64_t>()));
        }
      }
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "cdc-pgo: " << e.what() << '\n';
    return 1;
  }
}
