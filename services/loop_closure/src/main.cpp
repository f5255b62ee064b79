// cdc-loop-closure: a robot's loop-closure service (retrieval, verification, PCM).
#include "loop_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

#include <string>

namespace {

struct LoopFlags {
  std::string backlog_out, state_file;
};

void add_options(CLI::App& app, LoopFlags& f) {
  // What this service keeps on the shared options' domain and file.
  app.get_option("--local-domain")
      ->description(
          "the robot's own DDS domain: its keyframes, its own descriptors and a copy of its loop closures; "
          "default: none, all on --domain");
  app.get_option("--stats-out")->description("write counters and bytes per topic and peer (JSON) here at shutdown");
  app.add_option("--backlog-out", f.backlog_out,
                 "keep the work left here: descriptors waiting to be searched, cloud requests pending and parked, "
                 "loops published (one line, replaced as it changes)");
  app.add_option("--state-file", f.state_file,
                 "keep the loop numbering here, so that a restart under the same incarnation never reuses a loop's "
                 "sequence number (receivers would drop the new loop as a copy); default: none");
}

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-loop-closure",
      "finds loop closures of this robot's keyframes with its own past and with peers' keyframes\n"
      "(Scan Context descriptors received while in range), verifies each with GICP on the candidate's cloud (asked\n"
      "of its owner), keeps inter-robot loops that PCM finds consistent, and publishes them (withdrawals are\n"
      "explicit). Serves its own keyframes' clouds to peers. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2 cut and\n"
      "restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio.",
      "see services/loop_closure/config", rt::kRobotService};
  rt::ServiceOptions common;
  LoopFlags f;
  return rt::service_main(
      argc, argv, spec, common, [&](CLI::App& app) { add_options(app, f); },
      [&] {
        cdc::loops::LoopNodeOptions o = cdc::loops::load_loop_options(common.config);
        common.check_robot(o.robots);
        o.robot = common.robot;
        o.domain = common.domain_id();
        o.dds_config = common.dds_config;
        o.local_domain = common.local_domain;
        o.local_dds_config = common.local_dds_config;
        o.stats_out = common.stats_out;
        o.backlog_out = f.backlog_out;
        o.state_file = f.state_file;
        return rt::run_node<cdc::loops::LoopNode>(spec, common, o.log_level, o);
      });
}
