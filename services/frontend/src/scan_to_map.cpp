#include "cdc/frontend/scan_to_map.hpp"

namespace cdc::frontend {

ScanToMapRegistration::ScanToMapRegistration(const FrontendParams& params) : p_(params), recovery_(params) {}

Candidate ScanToMapRegistration::register_from(const Sweep& sweep, const RegistrationContext& ctx,
                                               const Eigen::Isometry3d& guess) const {
  return Candidate{odometry::register_to_map(sweep.points, sweep.normals, ctx.map, guess, ctx.params), {}, guess};
}

ScanToMapRegistration::Result ScanToMapRegistration::complete(const Eigen::Isometry3d& guess,
                                                              const RegistrationContext& ctx, Sweep& sweep,
                                                              Candidate& c, FrontendStats& stats) {
  if (ctx.redeskew && c.reg.converged) {
    // Deskew again with the motion just estimated (the prediction's error leaves a residual
    // distortion), and refine.
    sweep = ctx.redeskew(c.reg.T_target_source);
    c.reg = odometry::register_to_map(sweep.points, sweep.normals, ctx.map, c.reg.T_target_source, ctx.params);
  }
  c.fit = recovery_.fit_of(sweep, ctx.map, c.reg);
  Result out;
  // Recovery: a registration that failed, slid far from the prediction or fits the map clearly
  // worse than the sweeps before it (the prediction too far off for the gate: a sharp turn, a start
  // after standing still) is tried again from other guesses, and the best fit taken.
  if (p_.recovery.enabled && recovery_.poor(guess, c)) {
    ++stats.recovery_attempts;
    const RegistrationRecovery::Outcome o = recovery_.recover(guess, ctx, sweep, c);
    if (o.global) ++stats.recoveries_global;
    if (o.recovered) ++stats.recoveries;
    out.recovered = o.recovered;
  }
  out.reg = c.reg;
  out.fit = c.fit;
  // A registration that lands further from where it started than the widest gate (or turns more
  // than max_jump_rad) has slid into a wrong minimum, not followed the robot.
  if (out.reg.converged && !plausible_registration(c.start, out.reg.T_target_source, p_)) {
    out.reg.converged = false;
    ++stats.registration_rejected;
  }
  if (!out.reg.converged) {
    ++stats.registration_failures;
  } else {
    recovery_.remember_fit(c.fit.inlier_fraction);
  }
  return out;
}

}  // namespace cdc::frontend
