#include "swarm.hpp"

#include "cdc/base/names.hpp"
#include "cdc/config/reader.hpp"

#include <array>
#include <filesystem>
#include <optional>
#include <string_view>

namespace cdc::launch {
namespace fs = std::filesystem;

namespace {

constexpr std::array<base::Named<NetworkMode>, 3> kNetworkModeNames{
    {{NetworkMode::kAuto, "auto"}, {NetworkMode::kNetns, "netns"}, {NetworkMode::kLoopback, "loopback"}}};
constexpr std::array<base::Named<Variant>, 3> kVariantNames{
    {{Variant::kSingle, "single"}, {Variant::kDistributed, "distributed"}, {Variant::kSwitching, "switching"}}};

}  // namespace

const char* to_string(NetworkMode m) { return base::name_of(kNetworkModeNames, m, "?"); }
const char* to_string(Variant v) { return base::name_of(kVariantNames, v, "?"); }

std::optional<NetworkMode> parse_network_mode(std::string_view name) { return base::value_of(kNetworkModeNames, name); }

namespace {

// What runs, on which dataset and network.
void read_run(config::Reader& r, SwarmConfig& c) {
  r.get<std::string>(
      "name", c.name, [](const std::string& s) { return !s.empty() && s.find_first_of("/ \t") == std::string::npos; },
      "a name without spaces or slashes");
  r.get<std::string>("scenario", c.scenario);
  r.get<std::string>("dataset", c.dataset);
  int max_scans = 0;
  r.get_in("max_scans", max_scans, 0, 1'000'000);
  c.max_scans = static_cast<size_t>(max_scans);
  std::string network = to_string(NetworkMode::kAuto);
  r.get<std::string>(
      "network", network, [](const std::string& s) { return parse_network_mode(s).has_value(); },
      base::names_list(kNetworkModeNames));
  c.network = parse_network_mode(network).value_or(NetworkMode::kAuto);
}

// How it runs: playback, the system variant, the end of the mission.
void read_behaviour(config::Reader& r, SwarmConfig& c) {
  r.get<bool>("lockstep", c.lockstep);
  r.get_in("rate", c.rate, 0.01, 1000.0);
  r.get<bool>("lidar_only", c.lidar_only);
  std::string variant = to_string(Variant::kSwitching);
  r.get<std::string>(
      "variant", variant, [](const std::string& s) { return base::value_of(kVariantNames, s).has_value(); },
      base::names_list(kVariantNames));
  c.variant = base::value_of(kVariantNames, variant).value_or(Variant::kSwitching);
  r.get<bool>("frontend_correction", c.frontend_correction);
  r.get_in("settle_s", c.settle_s, 0.0, 3600.0);
  r.get<bool>("map", c.map);
  r.get_in("rendezvous_s", c.rendezvous_s, 0.0, 86400.0);
}

// The emulated radio: the dataset's range periods (or none) and the faults laid over them.
void read_radio(config::Reader& r, SwarmConfig& c) {
  r.get<bool>("range_periods", c.range_periods);
  YAML::Node faults;
  r.get<YAML::Node>("radio_faults", faults);
  std::vector<std::string> errors;
  c.radio_faults = parse_radio_faults(faults, errors);
  for (const std::string& e : errors) r.error(e);
  if (!c.radio_faults.empty() && c.network == NetworkMode::kLoopback)
    r.error("radio_faults need the netns network mode (loopback cannot drop single datagrams)");
}

void read_domains(config::Reader& r, SwarmConfig& c) {
  int slam = static_cast<int>(c.slam_domain), sim = static_cast<int>(c.sim_domain);
  int local_base = static_cast<int>(c.local_domain_base);
  auto domain = [](const int& v) { return v >= 0 && v <= 232; };
  r.get<int>("slam_domain", slam, domain, "0..232");
  r.get<int>("sim_domain", sim, domain, "0..232");
  r.get<int>("local_domain_base", local_base, domain, "0..232");
  c.local_domain_base = static_cast<uint32_t>(local_base);
  c.slam_domain = static_cast<uint32_t>(slam);
  c.sim_domain = static_cast<uint32_t>(sim);
}

// Relative paths from the project root; every service configuration and the scenario must exist.
void resolve_paths(config::Reader& r, SwarmConfig& c, const std::string& root) {
  auto resolve = [&](std::string& p) {
    if (!p.empty() && fs::path(p).is_relative()) p = (fs::path(root) / p).lexically_normal().string();
  };
  for (std::string* p : {&c.scenario, &c.dataset, &c.frontend_config, &c.descriptor_config, &c.loop_closure_config,
                         &c.peer_config, &c.central_config, &c.map_config}) {
    resolve(*p);
  }
  for (const std::string* p : {&c.frontend_config, &c.descriptor_config, &c.loop_closure_config, &c.peer_config,
                               &c.central_config, &c.map_config}) {
    if (!fs::is_regular_file(*p)) r.error("configs: " + *p + " does not exist");
  }
  if (!c.scenario.empty() && !fs::is_regular_file(c.scenario)) r.error("scenario: " + c.scenario + " does not exist");
}

}  // namespace

SwarmConfig load_swarm(const std::string& path, const std::string& root) {
  SwarmConfig c;
  c.path = path;
  if (!fs::is_regular_file(path)) throw config::ConfigError(path + ": no such swarm file");
  config::Reader r(path);
  read_run(r, c);
  read_domains(r, c);
  read_behaviour(r, c);
  read_radio(r, c);
  r.get<std::string>("configs.frontend", c.frontend_config);
  r.get<std::string>("configs.descriptor", c.descriptor_config);
  r.get<std::string>("configs.loop_closure", c.loop_closure_config);
  r.get<std::string>("configs.peer_optimiser", c.peer_config);
  r.get<std::string>("configs.central_optimiser", c.central_config);
  r.get<std::string>("configs.map", c.map_config);
  if (c.dataset.empty()) r.error("dataset: required (the folder is generated from 'scenario' when missing)");
  if (c.slam_domain == c.sim_domain)
    r.error("slam_domain and sim_domain must differ (sensors never cross the emulated radio)");
  resolve_paths(r, c, root);
  r.finish();
  return c;
}

}  // namespace cdc::launch
