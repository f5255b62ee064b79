// A simulated drive round a circle and a world built along it, for tests of place recognition and
// loop closure (the loops mission pattern of cdc/sim/missions.hpp).
#pragma once

#include "cdc/geometry/trajectory.hpp"
#include "cdc/sim/world.hpp"

#include <cstdint>

namespace cdc::test {

struct CircleLap {
  geometry::Trajectory lap;  // poses at the mission's rate, 2 m/s
  sim::World world;
};

// duration_s of driving round a circle of radius_m (one lap is 2 pi radius_m / 2 s); the world's
// objects are placed 8 m apart along the path, from `seed`.
CircleLap circle_lap(double radius_m, double duration_s, uint64_t seed = 3);

}  // namespace cdc::test
