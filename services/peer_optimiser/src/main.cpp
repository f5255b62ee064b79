// cdc-peer-optimiser: a robot's back-end agent (mode switching, distributed optimisation,
// corrections for the front-end, re-sends to the central).
#include "peer_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-peer-optimiser: the robot's back-end agent. Decides CENTRALIZED/DISTRIBUTED from the central's DDS\n"
      "liveliness and the estimated distance to it (RTDOS), relays or computes the robot's optimised poses,\n"
      "publishes fusion-limited corrections for the front-end, exchanges separator poses with peers, and\n"
      "re-sends to the central what it has not acknowledged. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2\n"
      "cut and restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio."};
  std::string config_path, dds_config, stats_out, log_level;
  std::string local_dds_config;
  int domain = -1, local_domain = -1;
  uint32_t robot = 0;
  app.add_option("--robot", robot, "this robot's id")->required()->check(CLI::Range(0, 254));
  app.add_option("--config", config_path, "YAML configuration (see services/peer_optimiser/config)")
      ->check(CLI::ExistingFile);
  app.add_option("--dds-config", dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--local-domain", local_domain,
                 "the robot's own DDS domain: its keyframes (forwarded to the central over --domain), loop closures "
                 "and corrections; default: none, all on --domain")
      ->check(CLI::Range(0, 232));
  app.add_option("--local-dds-config", local_dds_config, "Cyclone DDS configuration of the local domain (default: as --dds-config)");
  app.add_option("--stats-out", stats_out, "write counters (JSON) here at shutdown");
  std::string mode_out, trajectory_out, graph_out;
  app.add_option("--mode-out", mode_out, "write every mode transition (CSV) here as it happens");
  app.add_option("--trajectory-out", trajectory_out,
                 "write the robot's keyframes in the world frame as last corrected (TUM) here at shutdown");
  app.add_option("--graph-out", graph_out,
                 "write what this robot knows as a pose graph (g2o: its keyframes, the loops touching them, its "
                 "peers' separator poses) here at shutdown; cdc-peer-replay replays the robots' files together");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  try {
    cdc::peer::PeerNodeOptions o = cdc::peer::load_options(config_path);
    if (robot >= o.core.robot_count) {
      std::cerr << "cdc-peer-optimiser: --robot " << robot << " is not one of the " << o.core.robot_count
                << " robots of the configuration\n";
      return 2;
    }
    o.core.robot = robot;
    o.domain = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
    o.dds_config = dds_config;
    o.local_domain = local_domain;
    o.local_dds_config = local_dds_config;
    o.stats_out = stats_out;
    o.mode_out = mode_out;
    o.trajectory_out = trajectory_out;
    o.graph_out = graph_out;
    if (!log_level.empty()) {
      o.log_level = log_level;
    }
    cdc::runtime::init_logging("cdc-peer-optimiser-" + std::to_string(robot), o.log_level);
    return cdc::peer::run_peer(o);
  } catch (const cdc::config::ConfigError& e) {
    std::cerr << "cdc-peer-optimiser: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-peer-optimiser: " << e.what() << '\n';
    return 1;
  }
}
