// cdc-velodyne: a Velodyne's UDP data packets (or a pcap capture of them) decoded into sweeps and
// published on cdc/sensor/lidar, so that a robot needs no ROS driver.
#include "velodyne_driver_node.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/runtime/logging.hpp"

#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>
#include <random>

namespace {

using namespace cdc::velodyne_driver;

struct CommandLine {
  VelodyneNodeOptions node;
  std::string config, model, calibration, stats_out, log_level;
  int domain = -1, port = -1;
};

void add_options(CLI::App& app, CommandLine& c) {
  app.add_option("--robot", c.node.robot, "this robot's id")->required()->check(CLI::Range(0, 254));
  app.add_option("--config", c.config, "YAML configuration (see services/velodyne_driver/config)")->check(CLI::ExistingFile);
  app.add_option("--dds-config", c.node.dds_config, "Cyclone DDS configuration (file://...); default: CYCLONEDDS_URI");
  app.add_option("--domain", c.domain, "DDS domain id (default: CDC_DDS_DOMAIN or 0)")->check(CLI::Range(0, 232));
  app.add_option("--calibration", c.calibration, "the unit's calibration YAML (ROS driver format); overrides sensor.calibration")
      ->check(CLI::ExistingFile);
  app.add_option("--model", c.model, "VLP16, VLP32C, HDL32E, HDL64E, VLS128 or auto; overrides sensor.model");
  app.add_option("--bind", c.node.bind_address, "IPv4 address to listen on")->capture_default_str();
  app.add_option("--port", c.port, "UDP data port (default: udp.port, 2368)")->check(CLI::Range(1, 65535));
  app.add_option("--pcap", c.node.pcap, "replay this capture's datagrams to the data port instead of listening")
      ->check(CLI::ExistingFile);
  app.add_option("--rate", c.node.rate, "replay speed: 1 the capture's own, 2 twice as fast, 0 as fast as possible")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1000.0));
  app.add_option("--wait-readers", c.node.wait_readers, "wait up to 30 s for this many LiDAR readers before starting")
      ->capture_default_str();
  app.add_option("--stats-out", c.stats_out, "write counters (JSON) here at shutdown");
  app.add_option("--log-level", c.log_level, "trace, debug, info, warn, error");
}

int run(CommandLine& c) {
  VelodyneNodeOptions& o = c.node;
  o.driver = load_driver_config(c.config);
  if (!c.model.empty()) o.driver.model = parse_model(c.model);
  if (!c.calibration.empty()) o.driver.calibration = c.calibration;
  if (c.port > 0) o.driver.port = static_cast<uint16_t>(c.port);
  if (!c.log_level.empty()) o.driver.log_level = c.log_level;
  o.domain = c.domain >= 0 ? static_cast<uint32_t>(c.domain) : cdc::dds::domain_from_env(0);
  o.incarnation = std::random_device{}();
  cdc::runtime::init_logging("cdc-velodyne-" + std::to_string(o.robot), o.driver.log_level);
  VelodyneDriverNode node(o);
  const int code = node.spin();
  const VelodyneNodeStats s = node.stats();
  if (!c.stats_out.empty()) std::ofstream(c.stats_out) << to_json(s).dump(2) << '\n';
  spdlog::info("stopped after {} sweeps ({} points) from {} datagrams ({} skipped)", s.published, s.core.points,
               s.core.datagrams, s.core.datagrams - s.core.ok);
  return code;
}

}  // namespace

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{
      "cdc-velodyne: the robot's Velodyne driver. Decodes the sensor's UDP data packets (VLP-16, VLP-32C, HDL-32E,\n"
      "HDL-64E, VLS-128) into sweeps and publishes them on cdc/sensor/lidar (LidarScan: per-point time offsets and\n"
      "rings; stamps from the packets' arrival time). With --pcap it replays a capture through the same decoder.\n"
      "Stops cleanly on SIGINT/SIGTERM."};
  CommandLine c;
  add_options(app, c);
  CLI11_PARSE(app, argc, argv);
  try {
    return run(c);
  } catch (const cdc::config::ConfigError& e) {
    std::cerr << "cdc-velodyne: " << e.what() << '\n';
    return 2;
  } catch (const std::invalid_argument& e) {
    std::cerr << "cdc-velodyne: " << e.what() << '\n';
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cdc-velodyne: " << e.what() << '\n';
    return 1;
  }
}
