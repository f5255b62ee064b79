// g2o pose-graph files (cdc::graph::read_g2o): 3D and 2D vertices and edges, GTSAM symbol keys.
// Selector bit 0: skip malformed lines (with warnings) instead of failing.
#include "cdc/graph/g2o.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const cdc::fuzz::Input in(data, size);
  const std::string path = cdc::fuzz::write_file("graph.g2o", in.rest).string();
  std::vector<std::string> warnings;
  cdc::graph::G2oReadOptions options;
  options.skip_malformed = (in.selector & 1) != 0;
  options.warnings = &warnings;
  cdc::fuzz::refusals_pass([&] {
    const cdc::graph::PoseGraph graph = cdc::graph::read_g2o(path, options);
    for (const auto& [key, pose] : graph.poses) (void)cdc::graph::to_g2o_key(graph, key);
    (void)cdc::graph::loop_counts(graph);
  });
  return 0;
}
