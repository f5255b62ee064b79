// cdc-central-optimiser: the central node's global pose-graph optimiser.
#include "central_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

namespace {

struct CentralFlags {
  std::string graph_out;

  void declare(CLI::App& app) {
    app.add_option("--graph-out", graph_out, "write the final graph (g2o) here at shutdown");
  }
  void apply(cdc::central::CentralNodeOptions& o, const cdc::runtime::ServiceOptions&) const {
    o.graph_out = graph_out;
  }
};

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{"cdc-central-optimiser",
                             R"(one global pose graph for every robot in range. Subscribes keyframes, loop closures
and robots' world transforms; publishes optimised poses (liveliness-monitored), acknowledgements and the
central's status. Stops cleanly on SIGINT/SIGTERM.)",
                             "see services/central_optimiser/config", rt::kStatsOption};
  return rt::node_main<cdc::central::CentralNode>(argc, argv, spec, cdc::central::load_options, nullptr,
                                                  CentralFlags{});
}
