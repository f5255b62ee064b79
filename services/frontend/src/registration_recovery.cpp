#include "cdc/frontend/registration_recovery.hpp"

#include "cdc/frontend/adaptive_gate.hpp"
#include "cdc/geometry/se3.hpp"

#include <algorithm>

namespace cdc::frontend {

bool plausible_registration(const Eigen::Isometry3d& prediction, const Eigen::Isometry3d& registered,
                            const FrontendParams& p) {
  const Eigen::Isometry3d jump = prediction.inverse() * registered;
  return jump.translation().norm() <= p.max_gate_m && geometry::rotation_angle(jump.rotation()) <= p.max_jump_rad;
}

RegistrationRecovery::RegistrationRecovery(const FrontendParams& params) : p_(params) {}

odometry::FitQuality RegistrationRecovery::fit_of(const Sweep& sweep, const odometry::VoxelMap& map,
                                                  const odometry::RegistrationResult& reg) const {
  return odometry::evaluate_fit(sweep.points, sweep.normals, map, reg.T_target_source, p_.recovery.fit_distance_m,
                                p_.recovery.fit_inlier_m);
}

double RegistrationRecovery::recent_fit() const {
  if (recent_fits_.size() < p_.recovery.min_history) return 0.0;
  std::vector<double> f(recent_fits_.begin(), recent_fits_.end());
  std::nth_element(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(f.size() / 2), f.end());
  return f[f.size() / 2];
}

bool RegistrationRecovery::poor(const Eigen::Isometry3d& guess, const Candidate& c) const {
  if (!c.reg.converged || !plausible_registration(guess, c.reg.T_target_source, p_)) return true;
  return c.fit.inlier_fraction < p_.recovery.poor_fit_ratio * recent_fit();
}

// The registration from the prediction stays unless a candidate fits clearly better; it competes
// only if it is one the robot can have made. A candidate that fits as well as the recent sweeps
// (good_fit_ratio of their median) ends the search.
RegistrationRecovery::Outcome RegistrationRecovery::recover(const Eigen::Isometry3d& guess,
                                                            const RegistrationContext& ctx, Sweep& sweep,
                                                            Candidate& c) {
  const bool have = c.reg.converged && plausible_registration(guess, c.reg.T_target_source, p_);
  Search search;
  search.best = have ? c.fit.inlier_fraction + p_.recovery.min_gain : -1.0;
  const double median = recent_fit();
  search.good = median > 0 ? p_.recovery.good_fit_ratio * median : 2.0;
  // From the prediction with wide gates, then from the last pose (no motion).
  if (attempt(guess, ctx, search, sweep, c) || attempt(ctx.T_last, ctx, search, sweep, c)) return {true, false};
  if (!p_.recovery.global || prev_cloud_.empty()) return {search.replaced, false};
  const std::optional<Eigen::Isometry3d> global = global_guess(sweep, ctx.T_last);
  if (!global) return {search.replaced, false};
  const bool before = search.replaced;
  search.replaced = false;
  attempt(*global, ctx, search, sweep, c);
  return {search.replaced || before, search.replaced};
}

bool RegistrationRecovery::attempt(const Eigen::Isometry3d& start, const RegistrationContext& ctx, Search& search,
                                   Sweep& sweep, Candidate& c) const {
  // A deskewed sweep is deskewed with the motion its start implies, and again with the motion found.
  Sweep local;
  const Sweep* sw = &sweep;
  if (ctx.redeskew) {
    local = ctx.redeskew(start);
    sw = &local;
  }
  odometry::RegistrationResult r = coarse_to_fine(*sw, ctx, start);
  if (!r.converged) return false;
  r = odometry::register_to_map(sw->points, sw->normals, ctx.map, r.T_target_source, ctx.params);
  if (ctx.redeskew && r.converged) {
    local = ctx.redeskew(r.T_target_source);
    r = odometry::register_to_map(local.points, local.normals, ctx.map, r.T_target_source, ctx.params);
  }
  if (!r.converged || !plausible_registration(start, r.T_target_source, p_)) return false;
  const odometry::FitQuality f = fit_of(*sw, ctx.map, r);
  if (f.inlier_fraction <= search.best) return false;
  search.best = f.inlier_fraction;
  c = Candidate{r, f, start};
  if (ctx.redeskew) sweep = std::move(local);
  search.replaced = true;
  return search.best >= search.good;
}

// Coarse to fine: the wide gates reach a sweep the prediction left far off; the adaptive gate,
// registered with after them, fits it as the registration from the prediction does.
odometry::RegistrationResult RegistrationRecovery::coarse_to_fine(const Sweep& sweep, const RegistrationContext& ctx,
                                                                  const Eigen::Isometry3d& start) const {
  odometry::RegistrationResult r;
  r.T_target_source = start;
  r.converged = true;
  for (const double gate : p_.recovery.gates_m) {
    if (gate <= ctx.params.max_correspondence_m || !r.converged) break;
    r = odometry::register_to_map(sweep.points, sweep.normals, ctx.map, r.T_target_source,
                                  with_gate(ctx.params, gate, p_.kernel_divisor));
  }
  return r;
}

std::optional<Eigen::Isometry3d> RegistrationRecovery::global_guess(const Sweep& sweep,
                                                                    const Eigen::Isometry3d& T_last) {
  if (!prev_features_) prev_features_ = odometry::make_feature_cloud(prev_cloud_, p_.recovery.global_params);
  current_features_ = odometry::make_feature_cloud(sweep.cloud, p_.recovery.global_params);
  const odometry::GlobalRegistrationResult g =
      odometry::register_global(*current_features_, *prev_features_, p_.recovery.global_params);
  if (!g.ok) return std::nullopt;
  return T_last * g.T_target_source;
}

void RegistrationRecovery::remember_fit(double inlier_fraction) {
  recent_fits_.push_back(inlier_fraction);
  if (recent_fits_.size() > p_.recovery.fit_history) recent_fits_.pop_front();
}

void RegistrationRecovery::remember_sweep(std::vector<Eigen::Vector3d> cloud) {
  prev_cloud_ = std::move(cloud);
  prev_features_ = std::move(current_features_);
  current_features_.reset();
}

}  // namespace cdc::frontend
