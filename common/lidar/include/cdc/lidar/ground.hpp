// Where the ground lies below a LiDAR: the height of the ground around the sensor in its own frame.
// Two sweeps of one place taken at different heights above their ground (a sensor mounted higher, or
// trajectories whose elevations disagree between passes) differ by that offset before any
// registration: a verification started level with both grounds need not climb to it.
#pragma once

#include <Eigen/Core>

#include <optional>
#include <vector>

namespace cdc::lidar {

struct GroundOptions {
  double min_range_m = 2.0;   // horizontal distance from the sensor: nearer points are the vehicle's own
  double max_range_m = 40.0;  // farther ground rises or falls with the road's slope
  double percentile = 0.1;    // the ground is the floor of the points' heights, not their lowest outlier
  size_t min_points = 50;     // fewer points in range: no estimate
};

// The ground's height along `up` (a unit vector in the cloud's frame) relative to the sensor at the
// origin: the `percentile` of the heights of the points between min_range_m and max_range_m
// horizontally (negative for a sensor above its ground). nullopt when too few points are in range.
std::optional<double> ground_height(const std::vector<Eigen::Vector3f>& cloud, const Eigen::Vector3d& up,
                                    const GroundOptions& options = {});

}  // namespace cdc::lidar
