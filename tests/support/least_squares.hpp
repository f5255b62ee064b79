// Least-squares fits for benchmarks that report how a quantity grows (memory over time or per keyframe).
#pragma once

#include <cstddef>
#include <vector>

namespace cdc::test {

// Slope of the least-squares line of y over x; 0 with fewer than two points or no spread in x.
inline double slope(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() < 2 || y.size() != x.size()) return 0.0;
  const double n = static_cast<double>(x.size());
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    sx += x[i];
    sy += y[i];
    sxx += x[i] * x[i];
    sxy += x[i] * y[i];
  }
  const double d = n * sxx - sx * sx;
  return d == 0.0 ? 0.0 : (n * sxy - sx * sy) / d;
}

}  // namespace cdc::test
