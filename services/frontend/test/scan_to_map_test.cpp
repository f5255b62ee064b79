// Scan-to-map registration and its recovery, on sweeps of a hand-held VLP-16 standing in the
// simulated street (no per-point times): a sweep registers from a nearby guess, is deskewed again
// with the registered motion, and is rejected when it lands implausibly far from its start; a
// registration is judged against the recent fits, and a turn the prediction missed is recovered,
// from the last pose or from a global registration onto the previous sweep.
#include "simulated_drive.hpp"

#include "cdc/frontend/adaptive_gate.hpp"
#include "cdc/frontend/deskewing.hpp"
#include "cdc/frontend/registration_recovery.hpp"
#include "cdc/frontend/scan_to_map.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

namespace cdc::frontend {
namespace {

Eigen::Isometry3d turn_and_step(double yaw_deg, double metres) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw_deg * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation().x() = metres;
  return T;
}

// The map from the sweep at P0 (the map frame), and sweeps at other poses.
struct Scene {
  Drive d{8.0, 0.0, 4.0};  // only its world (a road with buildings, 40 m) is used
  FrontendParams p;
  Eigen::Isometry3d P0 = Eigen::Isometry3d::Identity();
  odometry::VoxelMap map{p.map};
  Sweep first;
  Scene() {
    P0.translation() = Eigen::Vector3d(12, 0, 1.73);
    first = sweep_at(P0);
    map.add(odometry::voxel_filter(first.cloud, p.map_voxel_m));
    // The map also holds the sweeps a metre behind and ahead, as a map built while driving does.
    for (const double x : {-1.0, 1.0}) {
      std::vector<Eigen::Vector3d> more =
          odometry::voxel_filter(sweep_at(P0 * turn_and_step(0, x)).cloud, p.map_voxel_m);
      for (auto& q : more) q = turn_and_step(0, x) * q;
      map.add(more);
    }
  }
  Sweep sweep_at(const Eigen::Isometry3d& P) {
    std::vector<ScanPoint> pts;
    for (const auto& q : sim::sweep(
             d.world, d.lidar, [&](double) { return P; }, d.rng)) {
      pts.push_back({Eigen::Vector3f(q.x, q.y, q.z), 0.0F, q.ring});
    }
    return Deskewer(p).prepare(0, pts, Eigen::Isometry3d::Identity(), DeskewImu{});
  }
  // The sweep at `truth` (map frame) registered from `guess` and completed.
  ScanToMapRegistration::Result register_at(const Eigen::Isometry3d& truth, const Eigen::Isometry3d& guess,
                                            const RegistrationContext& ctx, FrontendStats& stats) {
    Sweep sweep = sweep_at(P0 * truth);
    ScanToMapRegistration reg(p);
    Candidate c = reg.register_from(sweep, ctx, guess);
    return reg.complete(guess, ctx, sweep, c, stats);
  }
  // The registration's parameters with the gate at its minimum (after standing still).
  RegistrationContext narrow() const {
    return RegistrationContext{
        map, with_gate(p.registration, p.min_gate_m, p.kernel_divisor), Eigen::Isometry3d::Identity(), {}};
  }
  RegistrationContext wide() const {
    return RegistrationContext{
        map, with_gate(p.registration, p.initial_gate_m, p.kernel_divisor), Eigen::Isometry3d::Identity(), {}};
  }
};

double metres(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) { return (a.inverse() * b).translation().norm(); }
double degrees(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return geometry::rotation_angle((a.inverse() * b).rotation()) * 180 / M_PI;
}

TEST(ScanToMap, RegistersASweepFromANearbyGuess) {
  Scene s;
  const Eigen::Isometry3d truth = turn_and_step(5, 0.4);
  FrontendStats stats;
  const ScanToMapRegistration::Result r = s.register_at(truth, truth * turn_and_step(2, 0.15), s.wide(), stats);
  ASSERT_TRUE(r.reg.converged);
  // From 15 cm and 2 deg off: within 6 cm (along the road, which the scene constrains least) and 0.1 deg.
  EXPECT_LT(metres(r.reg.T_target_source, truth), 0.06);
  EXPECT_LT(degrees(r.reg.T_target_source, truth), 0.1);
  EXPECT_GT(r.fit.inlier_fraction, 0.8);
  EXPECT_FALSE(r.recovered);
  EXPECT_EQ(stats.registration_failures + stats.recovery_attempts, 0u);
}

TEST(ScanToMap, DeskewsAgainWithTheRegisteredMotion) {
  Scene s;
  const Eigen::Isometry3d truth = turn_and_step(5, 0.4);
  const Sweep original = s.sweep_at(s.P0 * truth);
  RegistrationContext ctx = s.wide();
  std::vector<Eigen::Isometry3d> asked;
  ctx.redeskew = [&](const Eigen::Isometry3d& T) {
    asked.push_back(T);
    return original;
  };
  FrontendStats stats;
  const ScanToMapRegistration::Result r = s.register_at(truth, truth * turn_and_step(1, 0.1), ctx, stats);
  ASSERT_EQ(asked.size(), 1u) << "once, with the pose registered";
  EXPECT_LT(metres(asked[0], truth), 0.06);
  EXPECT_TRUE(r.reg.converged);
}

TEST(ScanToMap, ARegistrationFarFromWhereItStartedIsRejected) {
  Scene s;
  s.p.max_gate_m = 0.05;  // a step of more than 5 cm is implausible
  s.p.recovery.enabled = false;
  const Eigen::Isometry3d truth = turn_and_step(0, 0.4);
  FrontendStats stats;
  const ScanToMapRegistration::Result r = s.register_at(truth, truth * turn_and_step(0, 0.3), s.wide(), stats);
  EXPECT_FALSE(r.reg.converged);
  EXPECT_EQ(stats.registration_rejected, 1u) << "converged 30 cm from its start";
  EXPECT_EQ(stats.registration_failures, 1u);
}

TEST(RegistrationRecovery, RegistrationsFarFromThePredictionAreImplausible) {
  FrontendParams p;  // max_gate_m 2 m, max_jump_rad 0.35
  Eigen::Isometry3d prediction = Eigen::Isometry3d::Identity();
  prediction.translation() = Eigen::Vector3d(10, 0, 1.7);
  Eigen::Isometry3d reg = prediction;
  reg.translation() += Eigen::Vector3d(0.5, 0.2, -0.1);
  EXPECT_TRUE(plausible_registration(prediction, reg, p));
  reg.translation() = prediction.translation() + Eigen::Vector3d(0.4, 0, -4.8);  // slid 4.8 m down
  EXPECT_FALSE(plausible_registration(prediction, reg, p));
  reg = prediction * Eigen::Isometry3d(Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()));
  EXPECT_FALSE(plausible_registration(prediction, reg, p));
  reg = prediction * Eigen::Isometry3d(Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitZ()));
  EXPECT_TRUE(plausible_registration(prediction, reg, p));
}

TEST(RegistrationRecovery, ARegistrationIsPoorAgainstTheRecentFits) {
  RegistrationRecovery rec{FrontendParams{}};  // poor under 0.75 of the median of at least 5
  Candidate c;
  c.reg.converged = true;
  c.fit.inlier_fraction = 0.1;
  EXPECT_EQ(rec.recent_fit(), 0.0);
  EXPECT_FALSE(rec.poor(Eigen::Isometry3d::Identity(), c)) << "too few fits to compare with";
  for (const double f : {0.8, 0.9, 0.7, 0.85, 0.95}) rec.remember_fit(f);
  EXPECT_DOUBLE_EQ(rec.recent_fit(), 0.85);
  c.fit.inlier_fraction = 0.6;
  EXPECT_TRUE(rec.poor(Eigen::Isometry3d::Identity(), c));
  c.fit.inlier_fraction = 0.7;
  EXPECT_FALSE(rec.poor(Eigen::Isometry3d::Identity(), c));
  c.reg.T_target_source = turn_and_step(0, 3.0);
  EXPECT_TRUE(rec.poor(Eigen::Isometry3d::Identity(), c)) << "slid 3 m";
  c.reg.T_target_source.setIdentity();
  c.reg.converged = false;
  EXPECT_TRUE(rec.poor(Eigen::Isometry3d::Identity(), c)) << "failed";
}

// A sweep the prediction missed, registered with the gate at its minimum (after standing still);
// the recent fits are this sweep's at the truth.
struct Missed {
  Scene s;
  Eigen::Isometry3d truth, T_last, guess;
  Sweep sweep;
  Missed(const Eigen::Isometry3d& truth_, const Eigen::Isometry3d& T_last_, const Eigen::Isometry3d& guess_,
         bool global)
      : truth(truth_), T_last(T_last_), guess(guess_) {
    s.p.recovery.global = global;
    sweep = s.sweep_at(s.P0 * truth);
  }
  // The robot stopped turning: the prediction carries the last sweep's turn on by 35 deg, the last
  // pose is 10 cm behind.
  static Missed overshot_turn() {
    const Eigen::Isometry3d T_last = turn_and_step(10, 0.3);
    return Missed(turn_and_step(10, 0.4), T_last, T_last * turn_and_step(35, 0), false);
  }
  RegistrationContext context() const {
    RegistrationContext ctx = s.narrow();
    ctx.T_last = T_last;
    return ctx;
  }
  void remember_truth(RegistrationRecovery& rec) const {
    odometry::RegistrationResult at_truth;
    at_truth.T_target_source = truth;
    const double f = rec.fit_of(sweep, s.map, at_truth).inlier_fraction;
    for (int k = 0; k < 5; ++k) rec.remember_fit(f);
  }
  // The registration from the prediction into `c` (poor: the turn the test needs), then recovered.
  RegistrationRecovery::Outcome recover(RegistrationRecovery& rec, Candidate& c) {
    const RegistrationContext ctx = context();
    c = ScanToMapRegistration(s.p).register_from(sweep, ctx, guess);
    c.fit = rec.fit_of(sweep, s.map, c.reg);
    std::printf("from the prediction: %.2f m %.1f deg off, fit %.2f\n", metres(c.reg.T_target_source, truth),
                degrees(c.reg.T_target_source, truth), c.fit.inlier_fraction);
    EXPECT_TRUE(rec.poor(guess, c)) << "the turn this test needs: the prediction alone loses it";
    return rec.recover(guess, ctx, sweep, c);
  }
  void expect_found(const Eigen::Isometry3d& T) const {
    EXPECT_LT(metres(T, truth), 0.06);
    EXPECT_LT(degrees(T, truth), 0.1);
  }
};

// Recovery of `m` with the recent fits at the truth and the first sweep as the previous one: the
// registration found, from a global registration or not.
void expect_recovered(Missed& m, bool from_global) {
  RegistrationRecovery rec(m.s.p);
  m.remember_truth(rec);
  rec.remember_sweep(m.s.first.cloud);
  Candidate c;
  const RegistrationRecovery::Outcome o = m.recover(rec, c);
  EXPECT_TRUE(o.recovered);
  EXPECT_EQ(o.global, from_global);
  m.expect_found(c.reg.T_target_source);
}

TEST(RegistrationRecovery, ATurnThePredictionOvershotIsRecoveredFromTheLastPose) {
  Missed m = Missed::overshot_turn();
  expect_recovered(m, false);
}

TEST(RegistrationRecovery, ATurnNoGuessReachesIsRecoveredFromAGlobalRegistration) {
  // Turned by 120 deg since the previous sweep, predicted as standing still.
  Missed m(turn_and_step(120, 0.4), Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), true);
  expect_recovered(m, true);
}

TEST(ScanToMap, APoorRegistrationIsRecoveredAndCounted) {
  Missed m = Missed::overshot_turn();
  ScanToMapRegistration reg(m.s.p);
  m.remember_truth(reg.recovery());
  const RegistrationContext ctx = m.context();
  Candidate c = reg.register_from(m.sweep, ctx, m.guess);
  FrontendStats stats;
  const ScanToMapRegistration::Result r = reg.complete(m.guess, ctx, m.sweep, c, stats);
  EXPECT_TRUE(r.recovered);
  EXPECT_EQ(stats.recovery_attempts, 1u);
  EXPECT_EQ(stats.recoveries, 1u);
  EXPECT_EQ(stats.registration_failures, 0u);
  ASSERT_TRUE(r.reg.converged);
  m.expect_found(r.reg.T_target_source);
}

}  // namespace
}  // namespace cdc::frontend
