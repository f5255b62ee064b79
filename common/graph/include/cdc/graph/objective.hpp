// Objectives evaluated on a pose graph's current estimate.
#pragma once

#include "cdc/graph/pose_graph.hpp"

namespace cdc::graph {

// sum_e r_e^T Omega_e r_e with r = (t_err, 2 vec(q_err)), no 1/2 factor (twice Ceres' cost).
double full_information_cost(const PoseGraph& graph);
// One factor's term r^T Omega r of full_information_cost at the graph's poses.
double squared_residual(const PoseGraph& graph, const Factor& factor);

// SE-Sync's objective (Rosen et al. 2019, no 1/2 factor):
//   sum_e kappa_e ||R_j - R_i R_ij||_F^2 + tau_e ||t_j - t_i - R_i t_ij||^2
// with isotropic weights from each information matrix (3D: tau = 3 / tr(inv(Omega_tt)),
// kappa = 3 / (2 tr(inv(Omega_RR))); 2D: tau = 2 / tr(inv(Omega_tt)), kappa = Omega_thth).
// Priors are not part of it.
double sesync_objective(const PoseGraph& graph);

struct IsotropicWeights {
  double tau = 0;
  double kappa = 0;
};
IsotropicWeights isotropic_weights(const Factor& factor, int dimension);

}  // namespace cdc::graph
