// cdc-sim scenario files (sim/tools/scenario.cpp): load_scenario's validation, then the scenario's
// LiDAR model (calibration errors drawn from the seed) for its first robots.
#include "scenario.hpp"
#include "fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string path = cdc::fuzz::write_file("scenario.yaml", {data, size}).string();
  cdc::fuzz::refusals_pass([&] {
    const cdc::sim::Scenario s = cdc::sim::load_scenario(path);
    for (int r = 0; r < std::min(s.robots, 4); ++r) (void)cdc::sim::scenario_lidar(s, r);
  });
  return 0;
}
