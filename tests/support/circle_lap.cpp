#include "circle_lap.hpp"

#include "cdc/sim/missions.hpp"

namespace cdc::test {

CircleLap circle_lap(double radius_m, double duration_s, uint64_t seed) {
  sim::MissionOptions mo;
  mo.pattern = sim::MissionPattern::kLoops;
  mo.robots = 1;
  mo.size_m = radius_m;
  mo.speed_mps = 2;
  mo.duration_s = duration_s;
  CircleLap out;
  out.lap = sim::procedural_mission(mo).front();
  std::vector<Eigen::Vector3d> path;
  for (const auto& sp : out.lap) path.push_back(sp.pose.translation());
  sim::WorldOptions wo;
  wo.seed = seed;
  wo.spacing_m = 8;
  out.world = sim::World::generate({path}, wo);
  return out;
}

}  // namespace cdc::test
