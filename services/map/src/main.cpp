// cdc-map: the map service. Keyframe clouds of every robot and the central optimiser's latest poses ->
// a global point cloud (.pcd) and an OctoMap (.bt), written on SIGUSR1, every write_period_s and at
// shutdown.
#include "map_node.hpp"

#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

#include <atomic>
#include <csignal>

namespace {
std::atomic<bool> g_write_requested{false};  // SIGUSR1, taken by ShutdownSignal's thread
}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-map",
      "the map service. Places every robot's keyframe clouds (cdc/frontend/keyframe) with the central\n"
      "optimiser's latest poses (cdc/central/optimized) into a global point cloud and an OctoMap; writes\n"
      "OUT/map.pcd and OUT/map.bt on SIGUSR1, every write_period_s and at shutdown (SIGINT/SIGTERM).",
      "see services/map/config", rt::kStatsOption};
  rt::ServiceOptions common;
  std::string out_dir = ".";
  const auto own = [&](CLI::App& app) { app.add_option("--out", out_dir, "output folder")->capture_default_str(); };
  return rt::service_main(argc, argv, spec, common, own, [&] {
    cdc::dds::ShutdownSignal::on_user_signal([](int signal) {
      if (signal == SIGUSR1) g_write_requested = true;
    });
    const cdc::map::MapNodeOptions o = cdc::map::load_map_options(common.config);
    return rt::run_node<cdc::map::MapNode>(spec, common, o.log_level, common, o, out_dir, g_write_requested);
  });
}
