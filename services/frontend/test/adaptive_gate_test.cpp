// The adaptive correspondence gate: the initial gate until five prediction errors are known, then
// three times their RMS within the limits, the kernel following the gate, the last hundred errors.
#include "cdc/frontend/adaptive_gate.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace cdc::frontend {
namespace {

// A registration `metres` and `radians` away from its prediction.
Eigen::Isometry3d off_by(double metres, double radians) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation().x() = metres;
  T.linear() = Eigen::AngleAxisd(radians, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

void record(AdaptiveGate& gate, size_t n, double metres, double radians) {
  for (size_t i = 0; i < n; ++i) gate.record(Eigen::Isometry3d::Identity(), off_by(metres, radians));
}

TEST(AdaptiveGate, StartsAtTheInitialGateUntilItKnowsFiveErrors) {
  FrontendParams p;
  p.initial_gate_m = 1.7;
  AdaptiveGate gate(p);
  EXPECT_DOUBLE_EQ(gate.params().max_correspondence_m, 1.7);
  EXPECT_DOUBLE_EQ(gate.params().kernel_m, 1.7 / p.kernel_divisor);
  record(gate, 4, 0.2, 0.0);
  EXPECT_DOUBLE_EQ(gate.params().max_correspondence_m, 1.7);
  record(gate, 1, 0.2, 0.0);
  EXPECT_NEAR(gate.params().max_correspondence_m, 0.6, 1e-12);
}

TEST(AdaptiveGate, FollowsThreeTimesTheRmsOfThePredictionsErrors) {
  AdaptiveGate gate{FrontendParams{}};
  record(gate, 5, 0.1, 0.0);
  record(gate, 5, 0.1, 0.02);  // 0.1 m + 10 m/rad * 0.02 rad = 0.3
  const double rms = std::sqrt((5 * 0.01 + 5 * 0.09) / 10.0);
  const odometry::RegistrationSettings rp = gate.params();
  EXPECT_NEAR(rp.max_correspondence_m, 3.0 * rms, 1e-9);
  EXPECT_NEAR(rp.kernel_m, 3.0 * rms / 9.0, 1e-9);
  EXPECT_EQ(rp.max_iterations, FrontendParams{}.registration.max_iterations) << "the rest as configured";
}

TEST(AdaptiveGate, StaysWithinItsLimits) {
  FrontendParams p;  // 0.3 to 2 m
  AdaptiveGate small(p), large(p);
  record(small, 10, 0.01, 0.0);
  record(large, 10, 5.0, 0.0);
  EXPECT_DOUBLE_EQ(small.params().max_correspondence_m, p.min_gate_m);
  EXPECT_DOUBLE_EQ(large.params().max_correspondence_m, p.max_gate_m);
}

TEST(AdaptiveGate, RemembersTheLastHundredErrors) {
  AdaptiveGate gate{FrontendParams{}};
  record(gate, 100, 5.0, 0.0);
  record(gate, 100, 0.2, 0.0);
  EXPECT_EQ(gate.history(), AdaptiveGate::kMaxHistory);
  EXPECT_NEAR(gate.params().max_correspondence_m, 0.6, 1e-12);
}

TEST(AdaptiveGate, AGateBringsItsKernel) {
  odometry::RegistrationSettings base;
  base.max_iterations = 7;
  const odometry::RegistrationSettings rp = with_gate(base, 1.8, 9.0);
  EXPECT_DOUBLE_EQ(rp.max_correspondence_m, 1.8);
  EXPECT_DOUBLE_EQ(rp.kernel_m, 0.2);
  EXPECT_EQ(rp.max_iterations, 7);
}

}  // namespace
}  // namespace cdc::frontend
