#include "cdc/lidar/ground.hpp"

#include <algorithm>
#include <cmath>

namespace cdc::lidar {

std::optional<double> ground_height(const std::vector<Eigen::Vector3f>& cloud, const Eigen::Vector3d& up,
                                    const GroundOptions& o) {
  std::vector<double> heights;
  heights.reserve(cloud.size());
  for (const Eigen::Vector3f& pf : cloud) {
    const Eigen::Vector3d p = pf.cast<double>();
    const double h = p.dot(up);
    const double horizontal = (p - h * up).norm();
    if (std::isfinite(h) && horizontal >= o.min_range_m && horizontal <= o.max_range_m) heights.push_back(h);
  }
  if (heights.size() < std::max<size_t>(o.min_points, 1)) return std::nullopt;
  const auto k = static_cast<std::ptrdiff_t>(o.percentile * static_cast<double>(heights.size() - 1));
  std::nth_element(heights.begin(), heights.begin() + k, heights.end());
  return heights[static_cast<size_t>(k)];
}

}  // namespace cdc::lidar
