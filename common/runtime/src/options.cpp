#include "cdc/runtime/options.hpp"

#include "cdc/config/cli_range.hpp"
#include "cdc/config/reader.hpp"
#include "cdc/dds/robot_domains.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>

#include <iostream>

namespace cdc::runtime {

uint32_t ServiceOptions::domain_id() const {
  return domain >= 0 ? static_cast<uint32_t>(domain) : dds::domain_from_env(0);
}

dds::ParticipantOptions ServiceOptions::radio() const {
  dds::ParticipantOptions p;
  p.domain_id = domain_id();
  p.config = dds_config;
  return p;
}

std::optional<dds::ParticipantOptions> ServiceOptions::local() const {
  return dds::local_domain_options(local_domain, local_dds_config, radio());
}

void ServiceOptions::check_robot(uint32_t robots) const {
  if (robot >= robots) {
    throw UsageError("--robot " + std::to_string(robot) + " is not one of the " + std::to_string(robots) +
                     " robots of the configuration");
  }
}

void add_shared_options(CLI::App& app, const ServiceSpec& spec, ServiceOptions& o) {
  if ((spec.shared & kRobotOption) != 0u) {
    app.add_option("--robot", o.robot, "this robot's id")->required()->check(cdc::config::cli_range(0, 254));
  }
  app.add_option("--config", o.config, "YAML configuration (" + spec.config_help + ")")->check(CLI::ExistingFile);
  app.add_option("--dds-config", o.dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", o.domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")
      ->check(cdc::config::cli_range(0, 232));
  if ((spec.shared & kLocalDomainOption) != 0u) {
    app.add_option("--local-domain", o.local_domain,
                   "the robot's own DDS domain, for what never crosses the radio; default: none, all on --domain")
        ->check(cdc::config::cli_range(0, 232));
    app.add_option("--local-dds-config", o.local_dds_config,
                   "Cyclone DDS configuration of the local domain (default: as --dds-config)");
  }
  if ((spec.shared & kStatsOption) != 0u) {
    app.add_option("--stats-out", o.stats_out, "write counters and traffic per topic (JSON) here at shutdown");
  }
  app.add_option("--log-level", o.log_level, "trace, debug, info, warn, error (default: the configuration's)");
}

void start_logging(const ServiceSpec& spec, const ServiceOptions& o, const std::string& config_level) {
  const bool robot = (spec.shared & kRobotOption) != 0u;
  init_logging(robot ? spec.name + "-" + std::to_string(o.robot) : spec.name,
               o.log_level.empty() ? config_level : o.log_level);
}

int service_main(int argc, char** argv, const ServiceSpec& spec, ServiceOptions& o,
                 const std::function<void(CLI::App&)>& own_options, const std::function<int()>& run) {
  dds::ShutdownSignal::install();
  CLI::App app{spec.name + ": " + spec.description};
  add_shared_options(app, spec, o);
  if (own_options) own_options(app);
  CLI11_PARSE(app, argc, argv);
  try {
    return run();
  } catch (const config::ConfigError& e) {
    std::cerr << spec.name << ": " << e.what() << '\n';
    return 2;
  } catch (const UsageError& e) {
    std::cerr << spec.name << ": " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << spec.name << ": " << e.what() << '\n';
    return 1;
  }
}

}  // namespace cdc::runtime
