// cdc-loop-closure: a robot's loop-closure service (retrieval, verification, PCM).
#include "loop_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-loop-closure: finds loop closures of this robot's keyframes with its own past and with peers' keyframes\n"
      "(Scan Context descriptors received while in range), verifies each with GICP on the candidate's cloud (asked\n"
      "of its owner), keeps inter-robot loops that PCM finds consistent, and publishes them (withdrawals are\n"
      "explicit). Serves its own keyframes' clouds to peers. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2 cut and\n"
      "restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio."};
  std::string config_path, dds_config, stats_out, backlog_out, log_level;
  std::string local_dds_config, state_file;
  int domain = -1, local_domain = -1;
  uint32_t robot = 0;
  app.add_option("--robot", robot, "this robot's id")->required()->check(CLI::Range(0, 254));
  app.add_option("--config", config_path, "YAML configuration (see services/loop_closure/config)")
      ->check(CLI::ExistingFile);
  app.add_option("--dds-config", dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--local-domain", local_domain,
                 "the robot's own DDS domain: its keyframes, its own descriptors and a copy of its loop closures; "
                 "default: none, all on --domain")
      ->check(CLI::Range(0, 232));
  app.add_option("--local-dds-config", local_dds_config, "Cyclone DDS configuration of the local domain (default: as --dds-config)");
  app.add_option("--stats-out", stats_out, "write counters and bytes per topic and peer (JSON) here at shutdown");
  app.add_option("--backlog-out", backlog_out,
                 "keep the work left here: descriptors waiting to be searched, cloud requests pending and parked, "
                 "loops published (one line, replaced as it changes)");
  app.add_option("--state-file", state_file,
                 "keep the loop numbering here, so that a restart under the same incarnation never reuses a loop's "
                 "sequence number (receivers would drop the new loop as a copy); default: none");
  app.add_option("--log-level", log_level, "trace, debug, info, warn, error");
  CLI11_PARSE(app, argc, argv);
  try {
    cdc::loops::LoopNodeOptions o = cdc::loops::load_loop_options(config_path);
    if (robot >= o.robots) {
      std::cerr << "cdc-loop-closure: --robot " << robot << " is not one of the " << o.robots
                << " robots of the configuration\n";
      return 2;
    }
    o.robot = robot;
    o.domain = domain >= 0 ? static_cast<uint32_t>(domain) : cdc::dds::domain_from_env(0);
    o.dds_config = dds_config;
    o.local_domain = local_domain;
    o.local_dds_config = local_dds_config;
    o.stats_out = stats_out;
    o.backlog_out = backlog_out;
    o.state_file = state_file;
    if (!log_level.empty()) o.log_level = log_level;
    cdc::runtime::init_logging("cdc-loop-closure-" + std::to_string(robot), o.log_level);
    return cdc::loops::run_loop_closure(o);
  } catch (const cdc::config::ConfigError& e) {
    std::cerr << "cdc-loop-closure: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-loop-closure: " << e.what() << '\n';
    return 1;
  }
}
