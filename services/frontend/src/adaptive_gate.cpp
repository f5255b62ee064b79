#include "cdc/frontend/adaptive_gate.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace cdc::frontend {

odometry::RegistrationSettings with_gate(odometry::RegistrationSettings base, double gate_m, double kernel_divisor) {
  base.max_correspondence_m = gate_m;
  base.kernel_m = gate_m / kernel_divisor;
  return base;
}

AdaptiveGate::AdaptiveGate(const FrontendParams& params) : p_(params) {}

odometry::RegistrationSettings AdaptiveGate::params() const {
  if (errors_.size() < kMinHistory) return with_gate(p_.registration, p_.initial_gate_m, p_.kernel_divisor);
  const double ms = std::accumulate(errors_.begin(), errors_.end(), 0.0, [](double a, double e) { return a + e * e; }) /
                    static_cast<double>(errors_.size());
  return with_gate(p_.registration, std::clamp(kSigmas * std::sqrt(ms), p_.min_gate_m, p_.max_gate_m),
                   p_.kernel_divisor);
}

void AdaptiveGate::record(const Eigen::Isometry3d& prediction, const Eigen::Isometry3d& registered) {
  const Eigen::Isometry3d dev = prediction.inverse() * registered;
  errors_.push_back(dev.translation().norm() + kMetresPerRadian * geometry::rotation_angle(dev.rotation()));
  if (errors_.size() > kMaxHistory) errors_.pop_front();
}

}  // namespace cdc::frontend
