#include "cdc/graph/distributed_robot.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "relax.hpp"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <limits>
#include <map>
#include <set>

namespace cdc::graph {
namespace {

using detail::LinearTerm;

// The change a round reports when nothing ties the robot's block to the world yet (no neighbour
// value received, no gauge, no prior): the stage is not done.
constexpr double kNotPlaced = std::numeric_limits<double>::infinity();
using Blocks = std::map<Key, Eigen::MatrixXd>;
using Triplets = std::vector<Eigen::Triplet<double>>;

// A stage's values at the separators (the keys some neighbour reads): what the robot sends.
template <class Value>
std::map<Key, Value> at_separators(const std::map<Key, std::set<uint32_t>>& audience,
                                   const std::map<Key, Value>& values) {
  std::map<Key, Value> out;
  for (const auto& [k, _] : audience) {
    out[k] = values.at(k);
  }
  return out;
}

// The normal equations of a linear block problem: H x = b over the unknown blocks.
struct NormalEquations {
  std::map<Key, int> index;  // unknown key -> block number
  int d;
  Triplets H;
  Eigen::MatrixXd b;
  bool anchored = false;  // some term ties the unknowns to a known value

  NormalEquations(const std::vector<Key>& unknown, int block)
      : d(block), b(Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(unknown.size()) * block, 3)) {
    for (Key k : unknown) {
      index.emplace(k, static_cast<int>(index.size()));
    }
  }
  void add(int r, int c, const Eigen::MatrixXd& M) {
    for (int i = 0; i < d; ++i) {
      for (int j = 0; j < d; ++j) {
        H.emplace_back(d * r + i, d * c + j, M(i, j));
      }
    }
  }
  auto rhs(int r) { return b.middleRows(d * r, d); }

  // Adds w ||x_j - A x_i - c||^2; xi / xj are the known values (null for an unknown).
  void add_term(const LinearTerm& t, int i, int j, const Eigen::MatrixXd* xi, const Eigen::MatrixXd* xj) {
    const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(d, d);
    if (i >= 0) {
      add(i, i, t.w * t.A.transpose() * t.A);
      rhs(i) += xj != nullptr ? Eigen::MatrixXd(t.w * t.A.transpose() * (*xj - t.c))
                              : Eigen::MatrixXd(-t.w * t.A.transpose() * t.c);
    }
    if (j >= 0) {
      add(j, j, t.w * I);
      rhs(j) += xi != nullptr ? Eigen::MatrixXd(t.w * (t.A * *xi + t.c)) : Eigen::MatrixXd(t.w * t.c);
    }
    if (i >= 0 && j >= 0) {
      add(i, j, -t.w * t.A.transpose());
      add(j, i, -t.w * t.A);
    } else {
      anchored = true;
    }
  }
};

// Minimises the sum of the terms over the `unknown` blocks, the other keys taken from `known`;
// a term naming a key in neither is left out. None when nothing ties the unknowns to a known value
// or the factorisation fails.
std::optional<Blocks> solve_linear(const std::vector<LinearTerm>& terms, const std::vector<Key>& unknown,
                                   const Blocks& known, int d) {
  NormalEquations eq(unknown, d);
  const auto lookup = [&](Key k, int* i, const Eigen::MatrixXd** x) {
    *x = nullptr;
    *i = -1;
    if (auto u = eq.index.find(k); u != eq.index.end()) {
      *i = u->second;
      return true;
    }
    auto v = known.find(k);
    *x = v != known.end() ? &v->second : nullptr;
    return *x != nullptr;
  };
  for (const LinearTerm& t : terms) {
    int i = -1, j = -1;
    const Eigen::MatrixXd *xi = nullptr, *xj = nullptr;
    if (!lookup(t.j, &j, &xj) || (t.i && !lookup(*t.i, &i, &xi)) || (i < 0 && j < 0)) {
      continue;
    }
    if (!t.i) {
      eq.anchored = true;  // a prior: x_j = c
    }
    eq.add_term(t, i, j, xi, xj);
  }
  if (!eq.anchored || unknown.empty()) {
    return std::nullopt;
  }
  const Eigen::Index n = static_cast<Eigen::Index>(unknown.size()) * d;
  Eigen::SparseMatrix<double> H(n, n);
  H.setFromTriplets(eq.H.begin(), eq.H.end());
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(H);
  if (ldlt.info() != Eigen::Success) {
    return std::nullopt;
  }
  const Eigen::MatrixXd x = ldlt.solve(eq.b);
  Blocks out;
  for (const auto& [k, i] : eq.index) {
    out[k] = x.middleRows(d * i, d);
  }
  return out;
}

// One round of a linear stage: the robot's linked keys are the unknowns, but for the gauge, held at
// gauge_value(key); the separators received are known. nullopt while the robot is not placed.
template <class Received, class GaugeValue>
std::optional<Blocks> linear_round(const std::vector<LinearTerm>& terms, const Received& received,
                                   const std::set<Key>& needed, const std::set<Key>& linked,
                                   const std::optional<Key>& gauge, int columns, const GaugeValue& gauge_value) {
  Blocks known;
  for (Key k : needed) {
    if (auto it = received.find(k); it != received.end()) known[k] = it->second.transpose();
  }
  std::vector<Key> unknown;
  for (Key k : linked) {
    if (gauge && k == *gauge) {
      known[k] = gauge_value(k);
    } else {
      unknown.push_back(k);
    }
  }
  return solve_linear(terms, unknown, known, columns);
}

// Robot r's own subgraph (intra-robot factors) initialised by chordal relaxation in a frame
// anchored at its first pose's current value (identity when it has none).
std::map<Key, Eigen::Isometry3d> local_chordal(const PoseGraph& graph, uint32_t r) {
  PoseGraph local;
  local.dimension = graph.dimension;
  for (const Factor& f : graph.factors) {
    if (robot_of(f.a) == r && robot_of(f.b) == r) {
      local.factors.push_back(f);
    }
  }
  for (const auto& [k, T] : graph.poses) {
    if (robot_of(k) == r && local.poses.empty()) {
      local.poses[k] = T;  // the first own pose keeps its value
    }
  }
  chordal_initialise(local);
  return local.poses;
}

}  // namespace

DistributedRobot::DistributedRobot(const PoseGraph& graph, uint32_t robot, std::optional<Key> gauge)
    : robot_(robot), dimension_(graph.dimension) {
  for (const Factor& f : graph.factors) {
    if (robot_of(f.a) != robot && robot_of(f.b) != robot) {
      continue;
    }
    factors_.push_back(f);
    if (f.kind != FactorKind::kPrior && f.inter_robot()) {
      const bool mine_is_a = robot_of(f.a) == robot;
      audience_[mine_is_a ? f.a : f.b].insert(robot_of(mine_is_a ? f.b : f.a));
      needed_.insert(mine_is_a ? f.b : f.a);
    }
  }
  poses_ = local_chordal(graph, robot);
  for (const auto& [k, T] : graph.poses) {
    if (robot_of(k) == robot) {
      poses_.emplace(k, T);  // poses no intra-robot factor reaches keep their value
    }
  }
  for (const Factor& f : factors_) {
    for (Key k : {f.a, f.b}) {
      if (robot_of(k) == robot) {
        linked_.insert(k);
        poses_.emplace(k, Eigen::Isometry3d::Identity());  // named by a factor only: placed by the rounds
      }
    }
  }
  if (gauge && robot_of(*gauge) == robot && poses_.count(*gauge) != 0) {
    gauge_ = gauge;
    pinned_.insert(*gauge);
  }
  for (const Factor& f : factors_) {
    if (f.kind == FactorKind::kPrior) {
      pinned_.insert(f.a);
    }
  }
  for (const auto& [k, T] : poses_) {
    relaxed_[k] = T.rotation();
  }
  for (const Factor& f : factors_) {
    const double kappa = isotropic_weights(f, dimension_).kappa;
    if (f.kind == FactorKind::kPrior) {
      rotation_terms_.push_back(
          {std::nullopt, f.a, Eigen::Matrix3d::Identity(), f.measurement.rotation().transpose(), kappa});
    } else {
      // M_b = M_a R_ab, as x = M^T:  x_b = R_ab^T x_a.
      rotation_terms_.push_back({f.a, f.b, f.measurement.rotation().transpose(), Eigen::Matrix3d::Zero(), kappa});
    }
  }
}

double DistributedRobot::rotation_round(const SeparatorRotations& received, double omega) {
  const std::optional<Blocks> x = linear_round(rotation_terms_, received, needed_, linked_, gauge_, 3,
                                               [this](Key k) { return Eigen::MatrixXd(relaxed_.at(k).transpose()); });
  if (!x) {
    return kNotPlaced;
  }
  double change = 0.0;
  for (const auto& [k, xk] : *x) {
    Eigen::Matrix3d& M = relaxed_.at(k);
    const Eigen::Matrix3d step = omega * (Eigen::Matrix3d(xk.transpose()) - M);
    M += step;
    change = std::max(change, step.norm());
  }
  return change;
}

SeparatorRotations DistributedRobot::rotation_separators() const { return at_separators(audience_, relaxed_); }

void DistributedRobot::end_rotations(const SeparatorRotations& received) {
  for (const auto& [k, M] : relaxed_) {
    poses_.at(k).linear() = geometry::project_to_so3(M);
  }
  for (Key k : needed_) {
    if (auto it = received.find(k); it != received.end()) {
      neighbour_rotations_[k] = geometry::project_to_so3(it->second);
    }
  }
  translation_terms_.clear();
  for (const Factor& f : factors_) {
    const double tau = isotropic_weights(f, dimension_).tau;
    const Eigen::MatrixXd one = Eigen::MatrixXd::Ones(1, 1);
    if (f.kind == FactorKind::kPrior) {
      translation_terms_.push_back({std::nullopt, f.a, one, f.measurement.translation().transpose(), tau});
      continue;
    }
    const bool own_a = robot_of(f.a) == robot_;
    const auto n = neighbour_rotations_.find(f.a);
    if (!own_a && n == neighbour_rotations_.end()) {
      continue;  // the neighbour's rotation never arrived
    }
    const Eigen::Matrix3d R_world_a = own_a ? poses_.at(f.a).rotation() : n->second;
    // t_b = t_a + R_a t_ab, as rows.
    translation_terms_.push_back({f.a, f.b, one, (R_world_a * f.measurement.translation()).transpose(), tau});
  }
}

double DistributedRobot::translation_round(const SeparatorTranslations& received, double omega) {
  const std::optional<Blocks> x =
      linear_round(translation_terms_, received, needed_, linked_, gauge_, 1,
                   [this](Key k) { return Eigen::MatrixXd(poses_.at(k).translation().transpose()); });
  if (!x) {
    return kNotPlaced;
  }
  double change = 0.0;
  for (const auto& [k, xk] : *x) {
    Eigen::Isometry3d& T = poses_.at(k);
    const Eigen::Vector3d step = omega * (Eigen::Vector3d(xk.transpose()) - T.translation());
    T.translation() += step;
    change = std::max(change, step.norm());
  }
  return change;
}

SeparatorTranslations DistributedRobot::translation_separators() const {
  SeparatorTranslations out;
  for (const auto& [k, _] : audience_) {
    out[k] = poses_.at(k).translation();
  }
  return out;
}

namespace {

// The local problem of stage 3: own poses from `start`, received separator poses held fixed.
struct PoseBlock {
  PoseGraph graph;
  std::set<Key> fixed;
  bool placed = false;  // something ties the block to the world
};

PoseBlock pose_block(const std::vector<Factor>& factors, const std::map<Key, Eigen::Isometry3d>& start,
                     const std::set<Key>& needed, const SeparatorPoses& received, std::optional<Key> gauge,
                     int dimension) {
  PoseBlock b;
  b.graph.dimension = dimension;
  b.graph.poses = start;
  for (Key k : needed) {
    if (auto it = received.find(k); it != received.end()) {
      b.graph.poses[k] = it->second;
      b.fixed.insert(k);
    }
  }
  if (gauge) {
    b.fixed.insert(*gauge);
  }
  b.placed = !b.fixed.empty();
  for (const Factor& f : factors) {
    if (b.graph.poses.count(f.a) != 0 && b.graph.poses.count(f.b) != 0) {
      b.graph.factors.push_back(f);
      b.placed = b.placed || f.kind == FactorKind::kPrior;
    }
  }
  b.placed = b.placed && !b.graph.factors.empty();
  return b;
}

}  // namespace

double DistributedRobot::pose_round(const SeparatorPoses& received, const SolverOptions& options, double gamma) {
  PoseBlock block = pose_block(factors_, poses_, needed_, received, gauge_, dimension_);
  if (!block.placed) {
    return kNotPlaced;
  }
  solve(block.graph, options, block.fixed);
  double max_change = 0.0;
  for (auto& [k, T] : poses_) {
    double change = 0.0;
    T = detail::relax_pose(T, block.graph.poses.at(k), gamma, &change);
    max_change = std::max(max_change, change);
  }
  return max_change;
}

double DistributedRobot::move(const CoarseCorrections& corrections) {
  double max_change = 0.0;
  for (Key k : linked_) {
    const Eigen::Isometry3d C = corrections.of(k);
    Eigen::Isometry3d& T = poses_.at(k);
    const Eigen::Isometry3d next = C * T;
    max_change =
        std::max({max_change, (next.translation() - T.translation()).norm(), Eigen::AngleAxisd(C.rotation()).angle()});
    T = next;
  }
  return max_change;
}

SeparatorPoses DistributedRobot::pose_separators() const { return at_separators(audience_, poses_); }

SeparatorPoses DistributedRobot::coarse_separators() const {
  SeparatorPoses out = pose_separators();
  for (const Factor& f : factors_) {
    // The other ends of inter-robot factors send their own.
    if (!f.inter_robot() && (pinned_.count(f.a) != 0 || pinned_.count(f.b) != 0)) {
      out[f.a] = poses_.at(f.a);
      out[f.b] = poses_.at(f.b);
    }
  }
  return out;
}

}  // namespace cdc::graph
