#include "cdc/graph/pcm.hpp"

#include "cdc/geometry/se3.hpp"

#include <Eigen/Cholesky>

#include <algorithm>
#include <array>
#include <limits>
#include <set>
#include <utility>

namespace cdc::graph {
namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Adjoint of T for tangent vectors ordered (translation, rotation), right perturbations:
// T * Exp(d) = Exp(Ad(T) d) * T.
Matrix6d adjoint(const Eigen::Isometry3d& T) {
  Matrix6d A = Matrix6d::Zero();
  A.topLeftCorner<3, 3>() = T.rotation();
  A.topRightCorner<3, 3>() = geometry::hat(T.translation()) * T.rotation();
  A.bottomRightCorner<3, 3>() = T.rotation();
  return A;
}

// T * Exp(d) to first order: rotation by the rotation vector, translation rotated into place.
Eigen::Isometry3d perturb(const Eigen::Isometry3d& T, const Vector6d& d) {
  Eigen::Isometry3d D = Eigen::Isometry3d::Identity();
  const double th = d.tail<3>().norm();
  if (th > 0) {
    D.linear() = Eigen::AngleAxisd(th, d.tail<3>() / th).toRotationMatrix();
  }
  D.translation() = d.head<3>();
  return T * D;
}

Vector6d residual(const Eigen::Isometry3d& E) {
  Vector6d r;
  r.head<3>() = E.translation();
  r.tail<3>() = geometry::so3_log(E.rotation());
  return r;
}

// The nearest rigid transform (rotation renormalised through its quaternion). Measurements may
// be orthonormal only to a few digits; composed along a chain of hundreds of them unchecked, the
// rotation's scale drifts, Isometry3d::inverse (a transpose) stops inverting, and the relative
// covariances below, differences of large cumulative ones, turn indefinite.
Eigen::Isometry3d rigid(const Eigen::Isometry3d& T) {
  return geometry::make_pose(T.translation(), Eigen::Quaterniond(T.linear()).normalized());
}

// Odometry of one robot: cumulative pose T_0k and covariance of T_0k (right perturbation, frame k),
// propagated to first order along its odometry factors.
struct Chain {
  std::map<uint64_t, Eigen::Isometry3d> pose;
  std::map<uint64_t, Matrix6d> cov;

  // T_ij with its covariance (right perturbation at j).
  std::pair<Eigen::Isometry3d, Matrix6d> relative(uint64_t i, uint64_t j) const {
    if (j < i) {
      const auto [T_ji, S_ji] = relative(j, i);
      const Matrix6d A = adjoint(T_ji);  // inverse: right perturbation moves by Ad(T_ji)
      return {T_ji.inverse(), A * S_ji * A.transpose()};
    }
    const Eigen::Isometry3d T_ij = pose.at(i).inverse() * pose.at(j);
    const Matrix6d A = adjoint(T_ij.inverse());
    // cov_0j = Ad(T_ij^-1) cov_0i Ad(T_ij^-1)^T + cov_ij
    Matrix6d S = cov.at(j) - A * cov.at(i) * A.transpose();
    S = 0.5 * (S + S.transpose());
    return {T_ij, S};
  }
};

// Parallel odometry factors (the same step measured twice) fused into one to first order: the
// information-weighted mean of their differences from the first, the sum of their information.
Factor fuse(const std::vector<const Factor*>& parallel) {
  Factor fused = *parallel.front();
  if (parallel.size() == 1) return fused;
  Matrix6d info = Matrix6d::Zero();
  Vector6d weighted = Vector6d::Zero();
  const Eigen::Isometry3d first = rigid(fused.measurement);
  for (const Factor* f : parallel) {
    info += f->information;
    weighted += f->information * residual(first.inverse() * rigid(f->measurement));
  }
  fused.measurement = perturb(first, info.ldlt().solve(weighted));
  fused.information = info;
  return fused;
}

std::map<uint32_t, Chain> odometry_chains(const PoseGraph& g) {
  // robot -> a index -> its odometry factors (several when the step is measured more than once)
  std::map<uint32_t, std::map<uint64_t, std::vector<const Factor*>>> parallel;
  for (const Factor& f : g.factors) {
    if (f.kind == FactorKind::kOdometry) {
      parallel[robot_of(f.a)][index_of(f.a)].push_back(&f);
    }
  }
  std::map<uint32_t, std::map<uint64_t, Factor>> by_start;
  for (const auto& [robot, steps] : parallel) {
    for (const auto& [a, factors] : steps) by_start[robot].emplace(a, fuse(factors));
  }
  std::map<uint32_t, Chain> chains;
  for (const auto& [robot, edges] : by_start) {
    Chain& c = chains[robot];
    uint64_t idx = edges.begin()->first;
    c.pose[idx] = Eigen::Isometry3d::Identity();
    c.cov[idx] = Matrix6d::Zero();
    for (auto it = edges.find(idx); it != edges.end(); it = edges.find(idx)) {
      const Factor& f = it->second;
      const uint64_t next = index_of(f.b);
      const Eigen::Isometry3d m = rigid(f.measurement);
      const Matrix6d A = adjoint(m.inverse());
      c.pose[next] = rigid(c.pose[idx] * m);
      c.cov[next] = A * c.cov[idx] * A.transpose() + f.information.inverse();
      idx = next;
    }
  }
  return chains;
}

// A loop as seen from the lower robot: T_lowkey_highkey.
struct Oriented {
  Key low, high;
  Eigen::Isometry3d T;
  Matrix6d cov;
};

Oriented orient(const Factor& f) {
  const Matrix6d cov = f.information.inverse();
  const Eigen::Isometry3d T = rigid(f.measurement);
  if (robot_of(f.a) <= robot_of(f.b)) {
    return {f.a, f.b, T, cov};
  }
  const Matrix6d A = adjoint(T);
  return {f.b, f.a, T.inverse(), A * cov * A.transpose()};
}

// Whether a robot's odometry reaches the key (a robot no odometry factor names has no chain at all).
bool reaches(const std::map<uint32_t, Chain>& chains, Key key) {
  const auto it = chains.find(robot_of(key));
  return it != chains.end() && it->second.pose.count(index_of(key)) != 0;
}

double cycle_distance_with(const std::map<uint32_t, Chain>& chains, const Factor& fk, const Factor& fl) {
  const Oriented k = orient(fk), l = orient(fl);
  // A loop end that the odometry does not reach cannot be checked: inconsistent with everything.
  if (!reaches(chains, k.low) || !reaches(chains, k.high) || !reaches(chains, l.low) || !reaches(chains, l.high)) {
    return std::numeric_limits<double>::infinity();
  }
  const Chain& A = chains.at(robot_of(k.low));
  const Chain& B = chains.at(robot_of(k.high));
  const auto [T_aa, S_aa] = A.relative(index_of(k.low), index_of(l.low));
  const auto [T_bb, S_bb] = B.relative(index_of(k.high), index_of(l.high));
  // Cycle: a_i -> b_j -> b_j' should equal a_i -> a_i' -> b_j'.
  auto cycle = [&](const Eigen::Isometry3d& Tk, const Eigen::Isometry3d& Tl, const Eigen::Isometry3d& Ta,
                   const Eigen::Isometry3d& Tb) { return residual((Ta * Tl).inverse() * Tk * Tb); };
  const Vector6d r = cycle(k.T, l.T, T_aa, T_bb);
  // First-order covariance of the cycle: numerical Jacobians with respect to each measurement.
  const std::array<const Matrix6d*, 4> covs = {&k.cov, &l.cov, &S_aa, &S_bb};
  Matrix6d S = Matrix6d::Zero();
  const double h = 1e-6;
  for (int m = 0; m < 4; ++m) {
    Matrix6d J;
    for (int c = 0; c < 6; ++c) {
      Vector6d d = Vector6d::Zero();
      d[c] = h;
      Eigen::Isometry3d Tk = k.T, Tl = l.T, Ta = T_aa, Tb = T_bb;
      (m == 0 ? Tk : m == 1 ? Tl : m == 2 ? Ta : Tb) = perturb(m == 0 ? Tk : m == 1 ? Tl : m == 2 ? Ta : Tb, d);
      J.col(c) = (cycle(Tk, Tl, Ta, Tb) - r) / h;
    }
    S += J * (*covs[static_cast<size_t>(m)]) * J.transpose();
  }
  return r.dot(S.ldlt().solve(r));
}

}  // namespace

double Pcm::odometry_distance(const PoseGraph& g, const Factor& loop) {
  const std::map<uint32_t, Chain> chains = odometry_chains(g);
  const auto it = chains.find(robot_of(loop.a));
  if (robot_of(loop.a) != robot_of(loop.b) || it == chains.end() || it->second.pose.count(index_of(loop.a)) == 0 ||
      it->second.pose.count(index_of(loop.b)) == 0) {
    return std::numeric_limits<double>::infinity();
  }
  const auto [T_odo, S_odo] = it->second.relative(index_of(loop.a), index_of(loop.b));
  const Eigen::Isometry3d E = T_odo.inverse() * rigid(loop.measurement);
  const Vector6d r = residual(E);
  // First order: the residual moves like the loop's right perturbation and against the odometry's.
  const Matrix6d A = adjoint(E.inverse());
  const Matrix6d S = loop.information.inverse() + A * S_odo * A.transpose();
  return r.dot(S.ldlt().solve(r));
}

double Pcm::cycle_distance(const PoseGraph& g, const Factor& k, const Factor& l) {
  return cycle_distance_with(odometry_chains(g), k, l);
}

OutlierDecision Pcm::decide(const PoseGraph& g) const {
  OutlierDecision out;
  const std::map<uint32_t, Chain> chains = odometry_chains(g);
  std::map<std::pair<uint32_t, uint32_t>, std::vector<size_t>> pairs;
  for (size_t f = 0; f < g.factors.size(); ++f) {
    const Factor& fa = g.factors[f];
    if (fa.kind != FactorKind::kLoop || !fa.inter_robot()) continue;
    if (!reaches(chains, fa.a) || !reaches(chains, fa.b)) {
      out.rejected.push_back(f);  // an end no odometry reaches (a robot with no trajectory): nothing checks it
      continue;
    }
    const uint32_t a = robot_of(fa.a), b = robot_of(fa.b);
    pairs[{std::min(a, b), std::max(a, b)}].push_back(f);
  }
  for (const auto& [pair, loops] : pairs) {
    const size_t n = loops.size();
    std::vector<std::vector<bool>> adj(n, std::vector<bool>(n, false));
    for (size_t x = 0; x < n; ++x) {
      for (size_t y = x + 1; y < n; ++y) {
        const double d2 = cycle_distance_with(chains, g.factors[loops[x]], g.factors[loops[y]]);
        adj[x][y] = adj[y][x] = d2 <= options_.chi2_threshold;
      }
    }
    const std::vector<size_t> clique = maximum_clique(adj, options_.exact_clique_limit);
    std::set<size_t> kept(clique.begin(), clique.end());
    for (size_t x = 0; x < n; ++x) {
      (kept.count(x) != 0 ? out.accepted : out.rejected).push_back(loops[x]);
    }
  }
  std::sort(out.accepted.begin(), out.accepted.end());
  std::sort(out.rejected.begin(), out.rejected.end());
  return out;
}

namespace {

// Greedy: grow a clique from every vertex, always adding the candidate of highest degree.
std::vector<size_t> greedy_clique(const std::vector<std::vector<bool>>& adj, const std::vector<size_t>& degree) {
  const size_t n = adj.size();
  std::vector<size_t> best;
  for (size_t s = 0; s < n; ++s) {
    std::vector<size_t> clique{s};
    std::vector<size_t> cand;
    for (size_t v = 0; v < n; ++v) {
      if (adj[s][v]) cand.push_back(v);
    }
    while (!cand.empty()) {
      const size_t v =
          *std::max_element(cand.begin(), cand.end(), [&](size_t a, size_t b) { return degree[a] < degree[b]; });
      clique.push_back(v);
      std::vector<size_t> next;
      for (size_t u : cand) {
        if (u != v && adj[v][u]) next.push_back(u);
      }
      cand.swap(next);
    }
    if (clique.size() > best.size()) best = clique;
  }
  return best;
}

// Exact maximum clique: branch and bound with a greedy-colouring bound (Tomita and Seki's MCQ),
// starting from a known clique. A colour class holds pairwise non-adjacent vertices, so a candidate
// set coloured with k colours holds no clique larger than k. Past max_steps expansions the search
// stops with the largest clique found so far (still a clique, perhaps not the largest).
class CliqueSearch {
 public:
  CliqueSearch(const std::vector<std::vector<bool>>& adj, std::vector<size_t> start, size_t max_steps)
      : adj_(adj), best_(std::move(start)), max_steps_(max_steps) {}

  // Searches from the candidates (all vertices, in order of decreasing degree, at the top level).
  void expand(const std::vector<size_t>& cand) {
    if (++steps_ > max_steps_) {
      aborted_ = true;
      return;
    }
    std::vector<size_t> order, colour;
    colour_greedily(cand, order, colour);
    for (size_t i = order.size(); i-- > 0;) {
      if (current_.size() + colour[i] <= best_.size()) return;  // bound
      const size_t v = order[i];
      std::vector<size_t> next;
      for (size_t j = 0; j < i; ++j) {
        if (adj_[v][order[j]]) next.push_back(order[j]);
      }
      current_.push_back(v);
      if (next.empty()) {
        if (current_.size() > best_.size()) best_ = current_;
      } else {
        expand(next);
      }
      current_.pop_back();
      if (aborted_) return;
    }
  }

  const std::vector<size_t>& best() const { return best_; }
  bool aborted() const { return aborted_; }

 private:
  // The candidates in order of colour class (each vertex into the first class it has no neighbour
  // in), with each vertex's colour 1, 2, ...: the bound on a clique among it and those before it.
  void colour_greedily(const std::vector<size_t>& cand, std::vector<size_t>& order, std::vector<size_t>& colour) const {
    std::vector<std::vector<size_t>> classes;
    for (size_t v : cand) {
      auto k = std::find_if(classes.begin(), classes.end(), [&](const std::vector<size_t>& c) {
        return std::none_of(c.begin(), c.end(), [&](size_t u) { return adj_[v][u]; });
      });
      if (k == classes.end()) {
        classes.emplace_back();
        k = classes.end() - 1;
      }
      k->push_back(v);
    }
    for (size_t k = 0; k < classes.size(); ++k) {
      for (size_t v : classes[k]) {
        order.push_back(v);
        colour.push_back(k + 1);
      }
    }
  }

  const std::vector<std::vector<bool>>& adj_;
  std::vector<size_t> best_;
  std::vector<size_t> current_;
  size_t max_steps_;
  size_t steps_ = 0;
  bool aborted_ = false;
};

}  // namespace

std::vector<size_t> maximum_clique(const std::vector<std::vector<bool>>& adj, size_t exact_limit, size_t max_steps,
                                   bool* exact) {
  const size_t n = adj.size();
  if (exact != nullptr) *exact = n <= exact_limit;
  if (n == 0) {
    return {};
  }
  std::vector<size_t> degree(n, 0);
  for (size_t i = 0; i < n; ++i) {
    degree[i] = static_cast<size_t>(std::count(adj[i].begin(), adj[i].end(), true));
  }
  std::vector<size_t> best = greedy_clique(adj, degree);
  if (n <= exact_limit) {
    std::vector<size_t> all(n);
    for (size_t i = 0; i < n; ++i) all[i] = i;
    std::sort(all.begin(), all.end(), [&](size_t a, size_t b) { return degree[a] > degree[b]; });
    CliqueSearch search(adj, std::move(best), max_steps);
    search.expand(all);
    if (exact != nullptr) *exact = !search.aborted();
    best = search.best();
  }
  std::sort(best.begin(), best.end());
  return best;
}

}  // namespace cdc::graph
