// cdc-peer-optimiser: a robot's back-end agent (mode switching, distributed optimisation,
// corrections for the front-end, re-sends to the central).
#include "peer_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

namespace {

struct PeerFlags {
  std::string mode_out, trajectory_out, graph_out;

  void declare(CLI::App& app) {
    app.get_option("--local-domain")
        ->description(
            "the robot's own DDS domain: its keyframes (forwarded to the central over --domain), loop closures "
            "and corrections; default: none, all on --domain");
    app.add_option("--mode-out", mode_out, "write every mode transition (CSV) here as it happens");
    app.add_option("--trajectory-out", trajectory_out,
                   "write the robot's keyframes in the world frame as last corrected (TUM) here at shutdown");
    app.add_option("--graph-out", graph_out,
                   "write what this robot knows as a pose graph (g2o: its keyframes, the loops touching them, its "
                   "peers' separator poses) here at shutdown; cdc-peer-replay replays the robots' files together");
  }
  void apply(cdc::peer::PeerNodeOptions& o, const cdc::runtime::ServiceOptions& common) const {
    o.core.robot = common.robot;
    o.mode_out = mode_out;
    o.trajectory_out = trajectory_out;
    o.graph_out = graph_out;
  }
};

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{"cdc-peer-optimiser",
                             R"(the robot's back-end agent. Decides CENTRALIZED/DISTRIBUTED from the central's DDS
liveliness and the estimated distance to it (RTDOS), relays or computes the robot's optimised poses,
publishes fusion-limited corrections for the front-end, exchanges separator poses with peers, and
re-sends to the central what it has not acknowledged. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2
cut and restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio.)",
                             "see services/peer_optimiser/config", rt::kRobotService};
  return rt::node_main<cdc::peer::PeerNode>(
      argc, argv, spec, cdc::peer::load_options, [](const cdc::peer::PeerNodeOptions& o) { return o.core.robot_count; },
      PeerFlags{});
}
