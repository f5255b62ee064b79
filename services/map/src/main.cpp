// cdc-map: the map service. Keyframe clouds of every robot and the central optimiser's latest poses ->
// a global point cloud (.pcd) and an OctoMap (.bt), written on SIGUSR1, every write_period_s and at
// shutdown.
#include "map_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

namespace {

struct MapFlags {
  std::string out_dir = ".";

  void declare(CLI::App& app) { app.add_option("--out", out_dir, "output folder")->capture_default_str(); }
  void apply(cdc::map::MapNodeOptions& o, const cdc::runtime::ServiceOptions&) const { o.out_dir = out_dir; }
};

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-map", R"(the map service. Places every robot's keyframe clouds (cdc/map/keyframe_cloud) with the central
optimiser's latest poses (cdc/central/optimized) into a global point cloud and an OctoMap; writes
OUT/map.pcd and OUT/map.bt on SIGUSR1, every write_period_s and at shutdown (SIGINT/SIGTERM).)",
      "see services/map/config", rt::kStatsOption};
  return rt::node_main<cdc::map::MapNode>(argc, argv, spec, cdc::map::load_map_options, nullptr, MapFlags{});
}
