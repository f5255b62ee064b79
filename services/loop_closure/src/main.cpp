// cdc-loop-closure: a robot's loop-closure service (retrieval, verification, PCM).
#include "loop_node.hpp"

#include "cdc/runtime/options.hpp"

#include <CLI/CLI.hpp>

#include <string>

namespace {

struct LoopFlags {
  std::string backlog_out, state_file;

  void declare(CLI::App& app) {
    // What this service keeps on the shared options' domain and file.
    app.get_option("--local-domain")
        ->description(
            "the robot's own DDS domain: its keyframes, its own descriptors and a copy of its loop closures; "
            "default: none, all on --domain");
    app.get_option("--stats-out")->description("write counters and bytes per topic and peer (JSON) here at shutdown");
    app.add_option("--backlog-out", backlog_out,
                   "keep the work left here: descriptors waiting to be searched, cloud requests pending and parked, "
                   "loops published (one line, replaced as it changes)");
    app.add_option("--state-file", state_file,
                   "keep the loop numbering here, so that a restart under the same incarnation never reuses a loop's "
                   "sequence number (receivers would drop the new loop as a copy); default: none");
  }
  void apply(cdc::loops::LoopNodeOptions& o, const cdc::runtime::ServiceOptions&) const {
    o.backlog_out = backlog_out;
    o.state_file = state_file;
  }
};

}  // namespace

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-loop-closure", R"(finds loop closures of this robot's keyframes with its own past and with peers' keyframes
(Scan Context descriptors received while in range), verifies each with GICP on the candidate's cloud (asked
of its owner), keeps inter-robot loops that PCM finds consistent, and publishes them (withdrawals are
explicit). Serves its own keyframes' clouds to peers. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2 cut and
restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio.)",
      "see services/loop_closure/config", rt::kRobotService};
  return rt::node_main<cdc::loops::LoopNode>(
      argc, argv, spec, cdc::loops::load_loop_options, [](const cdc::loops::LoopNodeOptions& o) { return o.robots; },
      LoopFlags{});
}
