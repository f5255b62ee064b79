// cdc-sim: the swarm simulator's command-line tool.
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/config/reader.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"
#include "player.hpp"
#include "scenario.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <random>

namespace {

// A city drive: straight streets joined by right-angle turns, 10 m/s, 1.7 m sensor height.
std::vector<Eigen::Vector3d> bench_path() {
  std::vector<Eigen::Vector3d> p;
  Eigen::Vector3d x(0, 0, 1.7);
  double heading = 0;
  for (int leg = 0; leg < 8; ++leg) {
    for (int i = 0; i < 150; ++i) {
      x += Eigen::Vector3d(std::cos(heading), std::sin(heading), 0);
      p.push_back(x);
    }
    heading += (leg % 3 == 2 ? -1 : 1) * M_PI / 2;
  }
  return p;
}

Eigen::Isometry3d pose_on(const std::vector<Eigen::Vector3d>& path, double s) {
  const size_t i = std::min(static_cast<size_t>(s), path.size() - 2);
  const double f = s - static_cast<double>(i);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = path[i] + f * (path[i + 1] - path[i]);
  const Eigen::Vector3d d = path[i + 1] - path[i];
  T.linear() = Eigen::AngleAxisd(std::atan2(d.y(), d.x()), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

int bench(int sweeps) {
  const auto path = bench_path();
  cdc::sim::WorldOptions wo;
  wo.seed = 7;
  const cdc::sim::World world = cdc::sim::World::generate({path}, wo);
  nlohmann::json j;
  uint64_t total_rays = 0;
  double total_s = 0;
  for (const auto& model : {cdc::sim::LidarModel::vlp16(), cdc::sim::LidarModel::hdl64()}) {
    std::mt19937_64 rng(1);
    size_t points = 0;
    const auto t0 = std::chrono::steady_clock::now();
    for (int k = 0; k < sweeps; ++k) {
      const double s0 = 1.0 * k;  // 1 m per sweep (10 m/s at 10 Hz)
      const auto pts = cdc::sim::sweep(
          world, model, [&](double t) { return pose_on(path, s0 + 10.0 * t); }, rng);
      points += pts.size();
    }
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    total_rays += static_cast<uint64_t>(sweeps) * model.rays();
    total_s += s;
    j[model.name + "_sweeps_per_s"] = sweeps / s;
    j[model.name + "_points_per_sweep"] = static_cast<double>(points) / sweeps;
    std::printf("%s: %.1f sweeps/s (%zu rays per sweep, %.0f points per sweep)\n", model.name.c_str(), sweeps / s,
                model.rays(), static_cast<double>(points) / sweeps);
  }
  j["vlp16_sweeps_per_s"] = j["vlp16_sweeps_per_s"];
  j["hdl64_sweeps_per_s"] = j["hdl64_sweeps_per_s"];
  j["rays_per_s"] = static_cast<double>(total_rays) / total_s;
  j["world_boxes"] = world.boxes().size();
  j["world_cylinders"] = world.cylinders().size();
  j["sweeps"] = sweeps;
  std::cout << j.dump() << '\n';
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-sim: the swarm simulator. Subcommands:\n"
      "  generate  write a dataset (per robot: velodyne scans with per-point times, IMU, ground truth; radio)\n"
      "  radio     the radio's out-of-range periods of a scenario (no sensor simulation)\n"
      "  play      publish a dataset over DDS (real time, faster, or lock-stepped); real recordings become\n"
      "            datasets with cdc-import\n"

      "  bench     ray-casting speed on one core (last line one JSON object)"};
  app.require_subcommand(1);
  const char* env_data = std::getenv("CDC_DATA_DIR");
  std::string data_dir = env_data != nullptr ? env_data : "../shared/data";
  std::string scenario_path, out_dir;
  size_t max_scans = 0;
  CLI::App* gen = app.add_subcommand("generate", "write a dataset from a scenario file");
  gen->add_option("--scenario", scenario_path, "scenario YAML (see sim/scenarios)")->required();
  gen->add_option("--out", out_dir, "output folder")->required();
  cdc::config::add_number_option(*gen, "--max-scans", max_scans, "scans per robot (0: all)", 0, 1e6);
  gen->add_option("--data", data_dir, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  cdc::sim::PlayOptions po;
  int domain = -1;
  std::string dataset_dir;
  auto play_options = [&](CLI::App* c) {
    cdc::config::add_number_option(*c, "--rate", po.rate, "1: real time, 2: twice as fast, 0: as fast as possible", 0,
                                   1000);
    c->add_flag("--lockstep", po.lockstep, "wait for each robot's consumer (cdc/sim/progress) before its next scan");
    cdc::config::add_number_option(*c, "--lockstep-timeout", po.lockstep_timeout_s, "[s]", 0.01, 3600);
    c->add_option("--wait-readers", po.wait_readers, "LiDAR readers to wait for before starting")
        ->check(cdc::config::cli_range(0, 1000));
    c->add_option("--max-scans", po.max_scans, "scans per robot (0: all)")->check(cdc::config::cli_range(0, 1e6));
    c->add_option("--clock-file", po.clock_file,
                  "after each sweep write '<stamp ns> <sweeps played>' here (atomically), for a launcher");
    c->add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
    c->add_option("--dds-config", po.dds_config, "Cyclone DDS configuration (default: CYCLONEDDS_URI)");
  };
  CLI::App* play = app.add_subcommand("play", "publish a dataset folder (cdc-sim generate, cdc-import)");
  play->add_option("dataset", dataset_dir, "dataset folder")->required();
  play->add_option("--robot", po.only_robot, "play only this robot's sensors (a player beside each robot)")
      ->check(CLI::Range(0, 254));
  play_options(play);
  CLI::App* radio = app.add_subcommand("radio", "out-of-range periods of a scenario, as JSON");
  radio->add_option("--scenario", scenario_path, "scenario YAML")->required();
  radio->add_option("--data", data_dir, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  int sweeps = 100;
  CLI::App* b = app.add_subcommand("bench", "sweeps per second for the VLP-16 and HDL-64E presets on one core");
  cdc::config::add_number_option(*b, "--sweeps", sweeps, "sweeps per preset", 1, 1e6);
  CLI11_PARSE(app, argc, argv);
  return cdc::base::run_tool(
      "cdc-sim",
      [&] {
        if (b->parsed()) {
          return bench(sweeps);
        }
        if (play->parsed()) {
          po.domain = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
          const auto sum = cdc::sim::play_dataset(dataset_dir, po);
          std::printf("played %zu scans, %zu IMU samples, %zu radio states\n", sum.scans, sum.imu_samples,
                      sum.radio_states);
          return 0;
        }
        const cdc::sim::Scenario sc = cdc::sim::load_scenario(scenario_path);
        cdc::sim::GenerateOptions go;
        go.data_dir = data_dir;
        go.max_scans = max_scans;
        go.stop = [] { return cdc::dds::ShutdownSignal::requested(); };
        if (radio->parsed()) {
          nlohmann::json j = nlohmann::json::array();
          for (const auto& p : cdc::sim::scenario_radio_periods(sc, go)) {
            j.push_back({{"a", p.a}, {"b", p.b}, {"start", p.start}, {"end", p.end}});
          }
          std::cout << j.dump() << '\n';
          return 0;
        }
        const auto t0 = std::chrono::steady_clock::now();
        const auto sum = cdc::sim::generate_dataset(sc, scenario_path, out_dir, go);
        std::printf("%s: %zu robots, %zu scans, %zu points, %zu out-of-range periods, %.1f s\n", out_dir.c_str(),
                    sum.robots, sum.scans, sum.points, sum.out_of_range_periods,
                    std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        return 0;
      },
      [](const std::exception& e) {
        if (dynamic_cast<const cdc::sim::Stopped*>(&e) != nullptr) {
          const int signal = cdc::dds::ShutdownSignal::signal_number();
          std::cerr << "cdc-sim: signal " << signal << ": nothing complete written\n";
          return 128 + signal;
        }
        return dynamic_cast<const cdc::config::ConfigError*>(&e) != nullptr ? 2 : 1;
      });
}
