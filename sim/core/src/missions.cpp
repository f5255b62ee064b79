#include "cdc/sim/missions.hpp"

#include <cmath>
#include <stdexcept>

namespace cdc::sim {
namespace {

struct Segment {
  double length;     // [m]
  double curvature;  // [1/m], + turns left
};

// Integrates a closed sequence of segments at constant speed from (start, heading), 10 Hz.
geometry::Trajectory drive(const std::vector<Segment>& lap, Eigen::Vector2d p, double heading, double speed,
                           double duration) {
  geometry::Trajectory out;
  const double dt = 0.1;
  size_t seg = 0;
  double along = 0;  // distance into the current segment
  const double step = speed * dt;
  for (int64_t k = 0; static_cast<double>(k) * dt <= duration + 1e-9; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(p.x(), p.y(), 0);
    T.linear() = Eigen::AngleAxisd(heading, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    out.push_back({k * 100'000'000LL, T});
    // Advance by `step` metres, integrating curvature exactly (arcs) in small sub-steps.
    double left = step;
    while (left > 1e-12) {
      const double room = lap[seg].length - along;
      const double ds = std::min(left, std::min(room, 0.05));
      const double k_c = lap[seg].curvature;
      if (std::abs(k_c) < 1e-12) {
        p += ds * Eigen::Vector2d(std::cos(heading), std::sin(heading));
      } else {
        const double h1 = heading + k_c * ds;
        p += Eigen::Vector2d(std::sin(h1) - std::sin(heading), std::cos(heading) - std::cos(h1)) / k_c;
        heading = h1;
      }
      along += ds;
      left -= ds;
      if (along >= lap[seg].length - 1e-12) {
        along = 0;
        seg = (seg + 1) % lap.size();
      }
    }
  }
  return out;
}

}  // namespace

std::optional<MissionPattern> parse_pattern(const std::string& name) {
  if (name == "rays") return MissionPattern::kRays;
  if (name == "loops") return MissionPattern::kLoops;
  if (name == "crossing") return MissionPattern::kCrossing;
  return std::nullopt;
}

std::vector<geometry::Trajectory> procedural_mission(const MissionOptions& o) {
  if (o.robots < 1 || o.speed_mps <= 0 || o.duration_s <= 0 || o.size_m <= 0) {
    throw std::invalid_argument("mission: robots, speed, duration and size must be positive");
  }
  std::vector<geometry::Trajectory> out;
  for (int k = 0; k < o.robots; ++k) {
    const double angle = 2 * M_PI * k / o.robots;
    const Eigen::Vector2d offset = 3.0 * k * Eigen::Vector2d(std::cos(angle + M_PI / 2), std::sin(angle + M_PI / 2));
    switch (o.pattern) {
      case MissionPattern::kRays: {
        const double R = o.turn_radius_m;
        const std::vector<Segment> lap = {{o.size_m, 0}, {M_PI * R, 1 / R}, {o.size_m, 0}, {M_PI * R, 1 / R}};
        out.push_back(drive(lap, offset, angle, o.speed_mps, o.duration_s));
        break;
      }
      case MissionPattern::kLoops: {
        const double r = o.size_m * (k + 1) / o.robots;
        out.push_back(
            drive({{2 * M_PI * r, 1 / r}}, Eigen::Vector2d(0, -r) + offset * 0, 0.0, o.speed_mps, o.duration_s));
        break;
      }
      case MissionPattern::kCrossing: {
        const double r = o.size_m / 4;
        const std::vector<Segment> eight = {{2 * M_PI * r, 1 / r}, {2 * M_PI * r, -1 / r}};
        out.push_back(drive(eight, offset, angle, o.speed_mps, o.duration_s));
        break;
      }
    }
  }
  return out;
}

}  // namespace cdc::sim
