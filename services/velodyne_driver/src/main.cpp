// cdc-velodyne: a Velodyne's UDP data packets (or a pcap capture of them) decoded into sweeps and
// published on cdc/sensor/lidar, so that a robot needs no ROS driver.
#include "velodyne_driver_node.hpp"

#include "cdc/config/cli_range.hpp"
#include "cdc/runtime/options.hpp"

#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <fstream>
#include <random>

namespace {

using namespace cdc::velodyne_driver;

struct CommandLine {
  VelodyneNodeOptions node;
  std::string model, calibration;
  int port = -1;
};

void add_options(CLI::App& app, CommandLine& c) {
  app.add_option("--calibration", c.calibration,
                 "the unit's calibration YAML (ROS driver format); overrides sensor.calibration")
      ->check(CLI::ExistingFile);
  app.add_option("--model", c.model,
                 "VLP16, VLP32C, HDL32E, HDL64E (S2), HDL64E_S3, VLS128 or auto; overrides sensor.model");
  app.add_option("--bind", c.node.bind_address, "IPv4 address to listen on")->capture_default_str();
  app.add_option("--port", c.port, "UDP data port (default: udp.port, 2368)")->check(cdc::config::cli_range(1, 65535));
  app.add_option("--pcap", c.node.pcap, "replay this capture's datagrams to the data port instead of listening")
      ->check(CLI::ExistingFile);
  cdc::config::add_number_option(app, "--rate", c.node.rate,
                                 "replay speed: 1 the capture's own, 2 twice as fast, 0 as fast as possible", 0, 1000);
  cdc::config::add_number_option(app, "--wait-readers", c.node.wait_readers,
                                 "wait up to 30 s for this many LiDAR readers before starting", 0, 1000);
}

int run(const cdc::runtime::ServiceSpec& spec, const cdc::runtime::ServiceOptions& common, CommandLine& c) {
  VelodyneNodeOptions& o = c.node;
  o.driver = load_driver_config(common.config);
  try {
    if (!c.model.empty()) o.driver.decoder.model = parse_model(c.model);
  } catch (const std::invalid_argument& e) {
    throw cdc::runtime::UsageError(e.what());
  }
  if (!c.calibration.empty()) o.driver.calibration = c.calibration;
  if (c.port > 0) o.driver.port = static_cast<uint16_t>(c.port);
  o.incarnation = std::random_device{}();
  cdc::runtime::start_logging(spec, common, o.driver.log_level);
  VelodyneDriverNode node(common, o);
  const int code = node.spin();
  const VelodyneNodeStats s = node.stats();
  if (!common.stats_out.empty()) std::ofstream(common.stats_out) << to_json(s).dump(2) << '\n';
  spdlog::info("stopped after {} sweeps ({} points) from {} datagrams ({} skipped)", s.published, s.core.points,
               s.core.datagrams, s.core.datagrams - s.core.ok);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-velodyne", R"(the robot's Velodyne driver. Decodes the sensor's UDP data packets (VLP-16, VLP-32C, HDL-32E,
HDL-64E, VLS-128) into sweeps and publishes them on cdc/sensor/lidar (LidarScan: per-point time offsets and
rings; stamps from the packets' arrival time). With --pcap it replays a capture through the same decoder.
Stops cleanly on SIGINT/SIGTERM.)",
      "see services/velodyne_driver/config", rt::kRobotOption | rt::kStatsOption};
  rt::ServiceOptions common;
  CommandLine c;
  return rt::service_main(
      argc, argv, spec, common, [&](CLI::App& app) { add_options(app, c); }, [&] { return run(spec, common, c); });
}
