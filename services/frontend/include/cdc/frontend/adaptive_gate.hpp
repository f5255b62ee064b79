// The adaptive correspondence gate (KISS-ICP): registration matches points no further apart than
// three times the prediction's recent error (the RMS over the last sweeps of the distance between
// where a sweep was predicted and where it registered, a turn weighing 10 m per radian), clamped
// to [min_gate_m, max_gate_m]; initial_gate_m until there are five. The robust kernel's scale
// follows the gate (gate / kernel_divisor).
#pragma once

#include "cdc/frontend/frontend_types.hpp"
#include "cdc/odometry/registration.hpp"

#include <Eigen/Geometry>

#include <deque>

namespace cdc::frontend {

// `base` with the correspondence gate `gate_m` and the kernel that goes with it.
odometry::RegistrationSettings with_gate(odometry::RegistrationSettings base, double gate_m, double kernel_divisor);

class AdaptiveGate {
 public:
  explicit AdaptiveGate(const FrontendParams& params);

  // The registration's parameters with the gate the recent errors give.
  odometry::RegistrationSettings params() const;
  // A sweep predicted at `prediction` registered at `registered`.
  void record(const Eigen::Isometry3d& prediction, const Eigen::Isometry3d& registered);
  size_t history() const noexcept { return errors_.size(); }

  static constexpr size_t kMinHistory = 5, kMaxHistory = 100;
  static constexpr double kMetresPerRadian = 10.0, kSigmas = 3.0;

 private:
  FrontendParams p_;
  std::deque<double> errors_;
};

}  // namespace cdc::frontend
