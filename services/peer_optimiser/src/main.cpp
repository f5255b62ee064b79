// cdc-peer-optimiser: a robot's back-end agent (mode switching, distributed optimisation,
// corrections for the front-end, re-sends to the central).
#include "peer_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

namespace {

struct PeerFlags {
  std::string mode_out, trajectory_out, graph_out;
};

void add_options(CLI::App& app, PeerFlags& f) {
  app.get_option("--local-domain")
      ->description(
          "the robot's own DDS domain: its keyframes (forwarded to the central over --domain), loop closures "
          "and corrections; default: none, all on --domain");
  app.add_option("--mode-out", f.mode_out, "write every mode transition (CSV) here as it happens");
  app.add_option("--trajectory-out", f.trajectory_out,
                 "write the robot's keyframes in the world frame as last corrected (TUM) here at shutdown");
  app.add_option("--graph-out", f.graph_out,
                 "write what this robot knows as a pose graph (g2o: its keyframes, the loops touching them, its "
                 "peers' separator poses) here at shutdown; cdc-peer-replay replays the robots' files together");
}

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-peer-optimiser",
      "the robot's back-end agent. Decides CENTRALIZED/DISTRIBUTED from the central's DDS\n"
      "liveliness and the estimated distance to it (RTDOS), relays or computes the robot's optimised poses,\n"
      "publishes fusion-limited corrections for the front-end, exchanges separator poses with peers, and\n"
      "re-sends to the central what it has not acknowledged. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2\n"
      "cut and restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio.",
      "see services/peer_optimiser/config", rt::kRobotService};
  rt::ServiceOptions common;
  PeerFlags f;
  return rt::service_main(
      argc, argv, spec, common, [&](CLI::App& app) { add_options(app, f); },
      [&] {
        cdc::peer::PeerNodeOptions o = cdc::peer::load_options(common.config);
        common.check_robot(o.core.robot_count);
        o.core.robot = common.robot;
        o.domain = common.domain_id();
        o.dds_config = common.dds_config;
        o.local_domain = common.local_domain;
        o.local_dds_config = common.local_dds_config;
        o.stats_out = common.stats_out;
        o.mode_out = f.mode_out;
        o.trajectory_out = f.trajectory_out;
        o.graph_out = f.graph_out;
        rt::start_logging(spec, common, o.log_level);
        cdc::peer::PeerNode node(o);
        node.spin();
        node.finish();
        return 0;
      });
}
