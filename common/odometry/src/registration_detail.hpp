// What the two registration methods share: one Gauss-Newton step's bookkeeping and the judging of
// a result (fitness, overlap, information).
#pragma once

#include "cdc/odometry/registration.hpp"

#include <vector>

namespace cdc::odometry::detail {

// Records the iteration `it` (n correspondences, sum2 their squared residuals, H and b the normal
// equations) in `out` and applies its update. False when the iterations end: converged (the update
// within the eps), or failed (fewer than 20 correspondences, an update not finite; a warning says so).
bool gauss_newton_step(const Matrix6d& H, const Eigen::Matrix<double, 6, 1>& b, int n, double sum2, int it,
                       const RegistrationSettings& s, RegistrationResult& out);
// After max_iterations without convergence: converged at the limit (with a warning) if the last
// iteration had enough correspondences.
void at_iteration_limit(const RegistrationSettings& s, RegistrationResult& out);

// Fitness and overlap from each source point's distance to its nearest target point.
void judge_overlap(const std::vector<double>& distances, double inlier_m, RegistrationResult& r);
// The information from the Hessian (right perturbation of T_target_source, both halves in the
// source's frame), its translation rotated into the target's frame; not positive definite: not
// converged.
void judge_information(double scale, RegistrationResult& r);

// Point-to-plane on two plain clouds (register_clouds).
RegistrationResult register_point_to_plane(const std::vector<Eigen::Vector3d>& source,
                                           const std::vector<Eigen::Vector3d>& target, const Eigen::Isometry3d& initial,
                                           const RegistrationSettings& s);

}  // namespace cdc::odometry::detail
