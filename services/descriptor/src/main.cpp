// cdc-descriptor: a robot's keyframes in, their Scan Context descriptors out. Only descriptors (about
// 0.6 KB each, packed) leave the robot by default; clouds stay home until a peer asks for one.
// Descriptors are sent once, live; a robot that missed some (out of range, or not matched yet) asks for
// the missing range on cdc/place/descriptor_sync and gets just those again.
#include "descriptor_node.hpp"

#include "cdc/runtime/options.hpp"

int main(int argc, char** argv) {
  namespace rt = cdc::runtime;
  const rt::ServiceSpec spec{
      "cdc-descriptor", R"(computes a Scan Context descriptor (quantised to one byte per cell) for every keyframe of
this robot and publishes it with the keyframe's pose hint. Stops cleanly on SIGINT/SIGTERM. SIGUSR1/SIGUSR2
cut and restore its SLAM domain (deaf and mute), the loopback launcher's emulated radio.)",
      "see services/descriptor/config", rt::kRobotService};
  return rt::node_main<cdc::descriptor::DescriptorNode>(
      argc, argv, spec, cdc::descriptor::load_descriptor_options,
      [](const cdc::descriptor::DescriptorNodeOptions& o) { return o.robots; });
}
