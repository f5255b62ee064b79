// cdc-central-optimiser: the central node's global pose-graph optimiser.
#include "central_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-central-optimiser",
      "one global pose graph for every robot in range. Subscribes keyframes, loop closures\n"
      "and robots' world transforms; publishes optimised poses (liveliness-monitored), acknowledgements and the\n"
      "central's status. Stops cleanly on SIGINT/SIGTERM.",
      "see services/central_optimiser/config", rt::kStatsOption};
  rt::ServiceOptions common;
  std::string graph_out;
  const auto own = [&](CLI::App& app) {
    app.add_option("--graph-out", graph_out, "write the final graph (g2o) here at shutdown");
  };
  return rt::service_main(argc, argv, spec, common, own, [&] {
    cdc::central::CentralNodeOptions o = cdc::central::load_options(common.config);
    o.domain = common.domain_id();
    o.dds_config = common.dds_config;
    o.graph_out = graph_out;
    o.stats_out = common.stats_out;
    return rt::run_node<cdc::central::CentralNode>(spec, common, o.log_level, o);
  });
}
