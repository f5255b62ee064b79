// The command line every service shares: which options exist, how they read, and what a service's
// main does around its own work (signals, parsing, errors and exit codes).
#pragma once

#include "cdc/dds/participant.hpp"
#include "cdc/runtime/memory.hpp"

#include <cstdint>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <utility>

namespace CLI {
class App;
}

namespace cdc::runtime {

// A command line that names something the configuration does not have (exit code 2, like a bad
// configuration).
class UsageError : public std::runtime_error {
 public:
  explicit UsageError(const std::string& what) : std::runtime_error(what) {}
};

// Shared options a service may declare (ServiceSpec::shared). --domain and --dds-config are always declared.
enum SharedOption : unsigned {
  kRobotOption = 1u << 0,        // --robot (required)
  kLocalDomainOption = 1u << 1,  // --local-domain, --local-dds-config: the robot's own domain
  kStatsOption = 1u << 2,        // --stats-out
};
inline constexpr unsigned kRobotService = kRobotOption | kLocalDomainOption | kStatsOption;

struct ServiceSpec {
  std::string name;         // process name, e.g. "cdc-loop-closure"
  std::string description;  // --help text
  std::string config_help;  // what --config holds, e.g. "see services/loop_closure/config"
  unsigned shared = kRobotService;
};

// What the shared options hold after parsing.
struct ServiceOptions {
  uint32_t robot = 0;
  std::string config;            // YAML file; empty: the service's defaults
  int domain = -1;               // SLAM domain; < 0: CDC_DDS_DOMAIN or 0
  std::string dds_config;        // empty: CYCLONEDDS_URI
  int local_domain = -1;         // < 0: none
  std::string local_dds_config;  // empty: as dds_config
  std::string stats_out;
  std::string log_level;  // empty: the configuration's

  uint32_t domain_id() const;
  dds::ParticipantOptions radio() const;
  // The robot's own domain, nullopt when it is none or the SLAM domain itself.
  std::optional<dds::ParticipantOptions> local() const;
  // Throws UsageError when --robot is not one of the configuration's robots.
  void check_robot(uint32_t robots) const;
};

// Declares the shared options of spec on app.
void add_shared_options(CLI::App& app, const ServiceSpec& spec, ServiceOptions& o);

// Starts logging as "<name>-<robot>" (or "<name>" without --robot) at --log-level, else config_level.
void start_logging(const ServiceSpec& spec, const ServiceOptions& o, const std::string& config_level);

// A service's main: installs the shutdown signals, declares the shared options and the service's own
// (own_options), parses, and runs `run`. A configuration or usage error prints "<name>: reason" and
// returns 2; any other exception returns 1; --help and parse errors as CLI11 does.
int service_main(int argc, char** argv, const ServiceSpec& spec, ServiceOptions& o,
                 const std::function<void(CLI::App&)>& own_options, const std::function<int()>& run);

// A node's life: logging started, the node built from args, run until shutdown (spin) and finished (its
// files and statistics written). Returns the exit code 0.
template <class Node, class... Args>
int run_node(const ServiceSpec& spec, const ServiceOptions& o, const std::string& config_level, Args&&... args) {
  start_logging(spec, o, config_level);
  return_large_blocks();
  Node node(std::forward<Args>(args)...);
  node.spin();
  node.finish();
  return 0;
}

// A service's own flags, as node_main takes them: declare(app) declares them on the command line,
// apply(options, shared) folds their values (and any shared option the options keep) into the options.
struct NoFlags {
  void declare(CLI::App&) {}
  template <class Options>
  void apply(Options&, const ServiceOptions&) const {}
};

// The main of a service whose node is Node(shared options, options): service_main around loading
// --config with load, checking --robot against robots(options) (services with --robot), applying the
// service's flags, and run_node at the configuration's log_level.
template <class Node, class Options, class Flags = NoFlags>
int node_main(int argc, char** argv, const ServiceSpec& spec, Options (*load)(const std::string&),
              uint32_t (*robots)(const std::type_identity_t<Options>&), Flags&& flags = Flags{}) {
  ServiceOptions common;
  return service_main(
      argc, argv, spec, common, [&](CLI::App& app) { flags.declare(app); },
      [&] {
        Options o = load(common.config);
        if ((spec.shared & kRobotOption) != 0u) common.check_robot(robots(o));
        flags.apply(o, common);
        return run_node<Node>(spec, common, o.log_level, common, o);
      });
}

}  // namespace cdc::runtime
