// cdc-central-optimiser: the central node's global pose-graph optimiser.
#include "central_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/error.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-central-optimiser: one global pose graph for every robot in range. Subscribes keyframes, loop closures\n"
      "and robots' world transforms; publishes optimised poses (liveliness-monitored), acknowledgements and the\n"
      "central's status. Stops cleanly on SIGINT/SIGTERM."};
  std::string config_path, dds_config, graph_out, stats_out, log_level;
  int domain = -1;
  app.add_option("--config", config_path, "YAML configuration (see services/central_optimiser/config)")
      ->check(CLI::ExistingFile);
  app.add_option("--dds-config", dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--graph-out", graph_out, "write the final graph (g2o) here at shutdown");
  app.add_option("--stats-out", stats_out, "write counters (JSON) here at shutdown");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  try {
    cdc::central::CentralNodeOptions o = cdc::central::load_options(config_path);
    o.domain = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
    o.dds_config = dds_config;
    o.graph_out = graph_out;
    o.stats_out = stats_out;
    if (!log_level.empty()) {
      o.log_level = log_level;
    }
    cdc::runtime::init_logging("cdc-central-optimiser", o.log_level);
    return cdc::central::run_central(o);
  } catch (const cdc::config::ConfigError& e) {
    std::cerr << "cdc-central-optimiser: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-central-optimiser: " << e.what() << '\n';
    return 1;
  }
}
