// Procedural multi-robot missions in the style of S3E: ground vehicles at constant speed along
// smooth paths (piecewise constant curvature), sampled at 10 Hz, all starting near the origin.
#pragma once

#include "cdc/geometry/trajectory.hpp"

#include <optional>
#include <string>
#include <vector>

namespace cdc::sim {

enum class MissionPattern {
  kRays,     // each robot laps a stadium along its own ray: out to `size_m` and back, every lap
  kLoops,    // concentric circles of growing radius around the start
  kCrossing  // figure-eights rotated per robot, crossing each other at the start
};
std::optional<MissionPattern> parse_pattern(const std::string& name);

struct MissionOptions {
  MissionPattern pattern = MissionPattern::kRays;
  int robots = 3;
  double duration_s = 120;
  double speed_mps = 5.0;
  double size_m = 150;       // ray length, largest radius, or figure-eight lobe radius x 4
  double turn_radius_m = 8;  // for stadium ends
};

std::vector<geometry::Trajectory> procedural_mission(const MissionOptions& options);

}  // namespace cdc::sim
