#include "cdc/graph/initialise.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/graph/objective.hpp"

#include <Eigen/SparseCholesky>

#include <deque>
#include <optional>
#include <unordered_map>
#include <vector>

namespace cdc::graph {
namespace {

Key anchor_key(const PoseGraph& g) {
  for (const Factor& f : g.factors) {
    if (f.kind == FactorKind::kPrior) {
      return f.a;
    }
  }
  if (!g.poses.empty()) {
    return g.poses.begin()->first;
  }
  Key k = g.factors.front().a;
  for (const Factor& f : g.factors) {
    k = std::min({k, f.a, f.b});
  }
  return k;
}

Eigen::Isometry3d anchor_pose(const PoseGraph& g, Key anchor) {
  for (const Factor& f : g.factors) {
    if (f.kind == FactorKind::kPrior && f.a == anchor) {
      return f.measurement;
    }
  }
  auto it = g.poses.find(anchor);
  return it != g.poses.end() ? it->second : Eigen::Isometry3d::Identity();
}

// Keys connected to the anchor, numbered 0.. with the anchor excluded (index -1).
struct Indexing {
  std::unordered_map<Key, int> index;
  std::vector<Key> keys;  // unknowns
  bool connected = true;
};

Indexing index_unknowns(const PoseGraph& g, Key anchor) {
  std::unordered_map<Key, std::vector<Key>> adj;
  for (const Factor& f : g.factors) {
    if (f.kind != FactorKind::kPrior) {
      adj[f.a].push_back(f.b);
      adj[f.b].push_back(f.a);
    }
  }
  Indexing ix;
  ix.index[anchor] = -1;
  std::deque<Key> q{anchor};
  while (!q.empty()) {
    const Key k = q.front();
    q.pop_front();
    for (Key n : adj[k]) {
      if (ix.index.emplace(n, static_cast<int>(ix.keys.size())).second) {
        ix.keys.push_back(n);
        q.push_back(n);
      }
    }
  }
  for (const auto& [k, _] : adj) {
    if (ix.index.count(k) == 0) {
      ix.connected = false;
    }
  }
  return ix;
}

// The factor joins two poses of the anchor's component (a graph that is not connected has others).
bool in_component(const Indexing& ix, const Factor& f) {
  return f.kind != FactorKind::kPrior && ix.index.count(f.a) != 0 && ix.index.count(f.b) != 0;
}

using Triplets = std::vector<Eigen::Triplet<double>>;

// Solves the symmetric system given by the triplets of its n x n matrix for the columns of b;
// nothing when the factorisation fails.
std::optional<Eigen::MatrixXd> solve_sparse(int n, const Triplets& triplets, const Eigen::MatrixXd& b) {
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(triplets.begin(), triplets.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
  if (ldlt.info() != Eigen::Success) {
    return std::nullopt;
  }
  return Eigen::MatrixXd(ldlt.solve(b));
}

// The rotation step's normal equations. The rows of the rotations decouple: with x_i = row r of R_i
// (a 1x3 row), each edge asks x_j - x_i R_ij = 0 with weight kappa. One 3n x 3n system, three
// right-hand sides (one per row r).
struct RotationSystem {
  Triplets H;
  Eigen::MatrixXd b;

  explicit RotationSystem(int n) : b(Eigen::MatrixXd::Zero(3 * n, 3)) {}

  void add_block(int r, int c, const Eigen::Matrix3d& M) {
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        if (M(i, j) != 0.0) {
          H.emplace_back(3 * r + i, 3 * c + j, M(i, j));
        }
      }
    }
  }

  // Edge i -> j (index -1: the anchor, whose rotation R0 is known) measuring Rij with weight kappa.
  void add_edge(int i, int j, const Eigen::Matrix3d& Rij, double kappa, const Eigen::Matrix3d& R0) {
    // Residual as column vectors: e = x_j^T - Rij^T x_i^T = [ -Rij^T  I ] [x_i; x_j].
    const Eigen::Matrix3d A_i = -Rij.transpose();
    const Eigen::Matrix3d I3 = Eigen::Matrix3d::Identity();
    if (i >= 0) add_block(i, i, kappa * A_i.transpose() * A_i);
    if (j >= 0) add_block(j, j, kappa * I3);
    if (i >= 0 && j >= 0) {
      add_block(i, j, kappa * A_i.transpose());
      add_block(j, i, kappa * A_i);
    }
    // Known anchor terms move to the right-hand side (for each row r of R_anchor).
    for (int r = 0; r < 3; ++r) {
      const Eigen::Vector3d x0 = R0.row(r).transpose();
      if (i < 0 && j >= 0) {
        b.block<3, 1>(3 * j, r) -= kappa * (A_i * x0);
      } else if (j < 0 && i >= 0) {
        b.block<3, 1>(3 * i, r) -= kappa * A_i.transpose() * x0;
      }
    }
  }
};

// Rotations of the unknowns by the chordal relaxation, projected onto SO(3); translations reset.
bool chordal_rotations(PoseGraph& graph, const Indexing& ix, const Eigen::Isometry3d& T0) {
  const int n = static_cast<int>(ix.keys.size());
  RotationSystem system(n);
  for (const Factor& f : graph.factors) {
    if (!in_component(ix, f)) {
      continue;
    }
    system.add_edge(ix.index.at(f.a), ix.index.at(f.b), f.measurement.rotation(),
                    isotropic_weights(f, graph.dimension).kappa, T0.rotation());
  }
  const std::optional<Eigen::MatrixXd> X = solve_sparse(3 * n, system.H, system.b);
  if (!X) {
    return false;
  }
  for (int k = 0; k < n; ++k) {
    Eigen::Matrix3d M;
    for (int r = 0; r < 3; ++r) {
      M.row(r) = X->block<3, 1>(3 * k, r).transpose();
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = geometry::project_to_so3(M);
    graph.poses[ix.keys[static_cast<size_t>(k)]] = T;
  }
  return true;
}

// Translations given the rotations: t_j - t_i = R_i t_ij with weight tau; coordinates decouple
// (weighted Laplacian).
bool chordal_translations(PoseGraph& graph, const Indexing& ix, const Eigen::Isometry3d& T0) {
  const int n = static_cast<int>(ix.keys.size());
  Triplets L;
  Eigen::MatrixXd b = Eigen::MatrixXd::Zero(n, 3);
  for (const Factor& f : graph.factors) {
    if (!in_component(ix, f)) {
      continue;
    }
    const double tau = isotropic_weights(f, graph.dimension).tau;
    const int i = ix.index.at(f.a), j = ix.index.at(f.b);
    const Eigen::Vector3d d = graph.poses.at(f.a).rotation() * f.measurement.translation();
    if (i >= 0) {
      L.emplace_back(i, i, tau);
      b.row(i) -= tau * d.transpose();
    }
    if (j >= 0) {
      L.emplace_back(j, j, tau);
      b.row(j) += tau * d.transpose();
    }
    if (i >= 0 && j >= 0) {
      L.emplace_back(i, j, -tau);
      L.emplace_back(j, i, -tau);
    } else if (i < 0 && j >= 0) {
      b.row(j) += tau * T0.translation().transpose();
    } else if (j < 0 && i >= 0) {
      b.row(i) += tau * T0.translation().transpose();
    }
  }
  const std::optional<Eigen::MatrixXd> X = solve_sparse(n, L, b);
  if (!X) {
    return false;
  }
  for (int k = 0; k < n; ++k) {
    graph.poses[ix.keys[static_cast<size_t>(k)]].translation() = X->row(k).transpose();
  }
  return true;
}

}  // namespace

bool chordal_initialise(PoseGraph& graph) {
  if (graph.factors.empty()) {
    return true;
  }
  const Key anchor = anchor_key(graph);
  const Eigen::Isometry3d T0 = anchor_pose(graph, anchor);
  const Indexing ix = index_unknowns(graph, anchor);
  graph.poses[anchor] = T0;
  if (ix.keys.empty()) {
    return ix.connected;
  }
  if (!chordal_rotations(graph, ix, T0) || !chordal_translations(graph, ix, T0)) {
    return false;
  }
  return ix.connected;
}

bool initialise_from_odometry(PoseGraph& graph) {
  if (graph.factors.empty()) {
    return true;
  }
  const Key anchor = anchor_key(graph);
  std::unordered_map<Key, std::vector<const Factor*>> adj;
  for (const Factor& f : graph.factors) {
    if (f.kind != FactorKind::kPrior) {
      adj[f.a].push_back(&f);
      adj[f.b].push_back(&f);
    }
  }
  std::unordered_map<Key, Eigen::Isometry3d> known;
  known[anchor] = anchor_pose(graph, anchor);
  std::deque<Key> q{anchor};
  while (!q.empty()) {
    const Key k = q.front();
    q.pop_front();
    for (const Factor* f : adj[k]) {
      const Key other = f->a == k ? f->b : f->a;
      if (known.count(other) != 0) {
        continue;
      }
      known[other] = f->a == k ? known[k] * f->measurement : known[k] * f->measurement.inverse();
      // Odometry first: chaining the trajectory before jumping along loop closures.
      if (f->kind == FactorKind::kOdometry) {
        q.push_front(other);
      } else {
        q.push_back(other);
      }
    }
  }
  for (const auto& [k, T] : known) {
    graph.poses[k] = T;
  }
  return known.size() == adj.size() || (adj.empty() && known.size() == 1);
}

}  // namespace cdc::graph
