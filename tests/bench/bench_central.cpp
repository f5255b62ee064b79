// cdc-bench-central: time of one incremental central-optimiser update (warm start, bounded
// iterations) on a 3-robot graph of 3,000 keyframes, as new keyframes and loops arrive. With --flood
// N, N keyframes of robot 1 whose ids never become contiguous arrive spread over the timed updates
// (a hostile writer): their intake time is reported, and the updates are timed under it. With
// --memory, the graph grows instead to --keyframes-per-robot with one update per step, the heap held
// the way the node holds it (runtime::return_large_blocks, free pages returned after whole-graph
// passes), and the heap in use and the resident memory are reported per keyframe over the second
// half. Last output line: one JSON object.
#include "cdc/central_optimiser/central_core.hpp"
#include "cdc/runtime/memory.hpp"
#include "least_squares.hpp"
#include "stream_to_central.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <malloc.h>
#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <fstream>
#include <iostream>

namespace {

// Processor time of the process (every thread) [ms]: less sensitive than wall time to other load.
double cpu_ms() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

double pct(std::vector<double> v, double p) {
  std::sort(v.begin(), v.end());
  return v[static_cast<size_t>(p * static_cast<double>(v.size() - 1))];
}

// Resident memory of the process [MB] and the heap in use by the program [MB].
std::pair<double, double> memory_mb() {
  long pages_total = 0, pages_resident = 0;
  std::ifstream("/proc/self/statm") >> pages_total >> pages_resident;
  const struct mallinfo2 m = mallinfo2();
  const double page_mb = static_cast<double>(sysconf(_SC_PAGESIZE)) / (1024.0 * 1024.0);
  return {static_cast<double>(pages_resident) * page_mb,
          static_cast<double>(m.uordblks + m.hblkhd) / (1024.0 * 1024.0)};
}

int run_memory(uint32_t per_robot) {
  cdc::runtime::return_large_blocks();
  cdc::test::SwarmStreamOptions o;
  o.robots = 3;
  o.keyframes_per_robot = per_robot;
  const auto stream = cdc::test::make_swarm_stream(o);
  cdc::central::CentralCore core(cdc::central::CentralConfig{});
  size_t next_loop = 0;
  std::vector<double> kf, rss, heap;
  double chunk_cpu = cpu_ms();
  for (uint32_t k = 0; k < per_robot; ++k) {
    for (const auto& robot : stream.keyframes) core.add_keyframe(cdc::test::to_central(robot[k]));
    while (next_loop < stream.loops.size() && stream.loops[next_loop].step <= k) {
      core.add_loop(cdc::test::to_central(stream.loops[next_loop++]));
    }
    if (core.optimise().full) cdc::runtime::release_free_memory();
    if ((k + 1) % 250 == 0) {
      const auto [r, h] = memory_mb();
      kf.push_back(static_cast<double>(core.graph().poses.size()));
      rss.push_back(r);
      heap.push_back(h);
      std::printf("%6.0f keyframes %6zu factors: resident %7.1f MB, heap in use %7.1f MB, %.2f ms CPU per keyframe\n",
                  kf.back(), core.graph().factors.size(), r, h, (cpu_ms() - chunk_cpu) / (250.0 * 3));
      chunk_cpu = cpu_ms();
    }
  }
  const size_t half = kf.size() / 2;
  const std::vector<double> x(kf.begin() + static_cast<long>(half), kf.end());
  const double rss_kb = cdc::test::slope(x, {rss.begin() + static_cast<long>(half), rss.end()}) * 1024.0;
  const double heap_kb = cdc::test::slope(x, {heap.begin() + static_cast<long>(half), heap.end()}) * 1024.0;
  std::printf("second half: resident %.2f KB and heap %.2f KB per keyframe\n", rss_kb, heap_kb);
  nlohmann::json j{{"keyframes", core.graph().poses.size()},
                   {"factors", core.graph().factors.size()},
                   {"rss_mb_end", rss.empty() ? 0.0 : rss.back()},
                   {"heap_mb_end", heap.empty() ? 0.0 : heap.back()},
                   {"rss_kb_per_keyframe", rss_kb},
                   {"heap_kb_per_keyframe", heap_kb}};
  std::cout << j.dump() << '\n';
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-bench-central: incremental central-optimiser update time on a 3-robot graph"};
  uint32_t per_robot = 1000;
  uint32_t updates = 60;
  uint32_t flood = 0;
  app.add_option("--keyframes-per-robot", per_robot, "graph size before timing, per robot")->capture_default_str();
  app.add_option("--updates", updates, "timed updates (one keyframe per robot each)")->capture_default_str();
  app.add_option("--flood", flood, "non-contiguous keyframes of robot 1 spread over the timed updates")
      ->capture_default_str();
  bool memory = false;
  app.add_flag("--memory", memory, "grow the graph to --keyframes-per-robot and report memory per keyframe");
  CLI11_PARSE(app, argc, argv);
  if (memory) return run_memory(per_robot);

  cdc::test::SwarmStreamOptions o;
  o.robots = 3;
  o.keyframes_per_robot = per_robot + updates;
  const auto stream = cdc::test::make_swarm_stream(o);
  cdc::central::CentralCore core(cdc::central::CentralConfig{});
  size_t next_loop = 0;
  auto feed_step = [&](uint32_t k) {
    for (const auto& robot : stream.keyframes) {
      core.add_keyframe(cdc::test::to_central(robot[k]));
    }
    while (next_loop < stream.loops.size() && stream.loops[next_loop].step <= k) {
      core.add_loop(cdc::test::to_central(stream.loops[next_loop++]));
    }
  };
  for (uint32_t k = 0; k < per_robot; ++k) {
    feed_step(k);
    if (k % 25 == 24) {
      core.optimise();  // the central keeps up while the graph grows
    }
  }
  core.optimise_fully();
  std::vector<double> ms, cpu;
  std::vector<int> iterations;
  std::vector<double> solver_ms, local_ms, full_ms, local_factors;
  cdc::central::KeyframeIn hostile = cdc::test::to_central(stream.keyframes[1][0]);
  uint32_t flooded = 0;
  double flood_s = 0;
  for (uint32_t k = per_robot; k < per_robot + updates; ++k) {
    const auto f0 = std::chrono::steady_clock::now();
    for (const uint32_t until = flood / updates * (k - per_robot + 1); flooded < until; ++flooded) {
      hostile.id = 1'000'000 + 2 * flooded;
      core.add_keyframe(hostile);
    }
    flood_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - f0).count();
    feed_step(k);
    const auto t0 = std::chrono::steady_clock::now();
    const double c0 = cpu_ms();
    const auto st = core.optimise();
    cpu.push_back(cpu_ms() - c0);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    iterations.push_back(st.iterations);
    solver_ms.push_back(st.time_s * 1e3);
    (st.full ? full_ms : local_ms).push_back(ms.back());
    if (!st.full) local_factors.push_back(static_cast<double>(st.factors));
  }
  nlohmann::json j{{"keyframes", core.graph().poses.size()},
                   {"factors", core.graph().factors.size()},
                   {"updates", updates},
                   {"update_ms_median", pct(ms, 0.5)},
                   {"update_ms_p90", pct(ms, 0.9)},
                   {"update_ms_max", pct(ms, 1.0)},
                   {"update_ms_min", pct(ms, 0.0)},
                   {"update_cpu_ms_median", pct(cpu, 0.5)},
                   {"iterations_median", iterations[iterations.size() / 2]},
                   {"ceres_ms_median", pct(solver_ms, 0.5)},
                   {"local_updates", local_ms.size()},
                   {"local_update_ms_median", local_ms.empty() ? 0.0 : pct(local_ms, 0.5)},
                   {"local_factors_median", local_factors.empty() ? 0.0 : pct(local_factors, 0.5)},
                   {"full_updates", full_ms.size()},
                   {"full_update_ms_median", full_ms.empty() ? 0.0 : pct(full_ms, 0.5)},
                   {"flood_keyframes", flooded},
                   {"flood_refused", core.counters().keyframes_pending_full},
                   {"flood_intake_us_per_keyframe", flooded == 0 ? 0.0 : flood_s * 1e6 / flooded}};
  std::printf("central update on %zu keyframes: median %.1f ms, p90 %.1f ms, max %.1f ms over %u updates",
              core.graph().poses.size(), pct(ms, 0.5), pct(ms, 0.9), pct(ms, 1.0), updates);
  if (flooded > 0) {
    std::printf("; under a flood of %u keyframes (%.2f us each)", flooded, flood_s * 1e6 / flooded);
  }
  std::printf("\n");
  std::cout << j.dump() << '\n';
  return 0;
}
