// Graduated non-convexity on a small synthetic graph with wrong loop closures.
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/solver.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace cdc::graph {
namespace {

Eigen::Isometry3d pose(const Eigen::Vector3d& t, const Eigen::Vector3d& rotation_vector) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const double angle = rotation_vector.norm();
  if (angle > 0) T.linear() = Eigen::AngleAxisd(angle, rotation_vector / angle).toRotationMatrix();
  T.translation() = t;
  return T;
}

// Three turns of a helix (radius 5 m, 20 poses a turn), odometry and loops one turn apart, with
// noise that matches their information (0.02 m, 0.01 rad); then `wrong` loops between random
// poses with random relative poses (metres off). The truth is returned in `truth`.
PoseGraph noisy_helix_with_wrong_loops(int wrong, std::vector<Eigen::Isometry3d>& truth) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  const int turn = 20, n = 3 * turn;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / turn;
    truth.push_back(pose({5 * std::cos(a), 5 * std::sin(a), 0.3 * i}, {0, 0, a + M_PI / 2}));
  }
  Matrix6d info = Matrix6d::Identity();
  info.topLeftCorner<3, 3>() *= 1.0 / (0.02 * 0.02);
  info.bottomRightCorner<3, 3>() *= 1.0 / (0.01 * 0.01);
  auto noisy = [&](const Eigen::Isometry3d& T) {
    return T * pose({0.02 * n01(rng), 0.02 * n01(rng), 0.02 * n01(rng)},
                    {0.01 * n01(rng), 0.01 * n01(rng), 0.01 * n01(rng)});
  };
  PoseGraph g;
  auto key = [](int i) { return make_key(0, static_cast<uint64_t>(i)); };
  auto at = [&](int i) { return truth[static_cast<size_t>(i)]; };
  for (int i = 0; i + 1 < n; ++i) g.add_between(key(i), key(i + 1), noisy(at(i).inverse() * at(i + 1)), info);
  for (int i = 0; i + turn < n; i += 2)
    g.add_between(key(i), key(i + turn), noisy(at(i).inverse() * at(i + turn)), info);
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  for (int added = 0; added < wrong;) {
    const int a = pick(rng), b = pick(rng);
    if (std::abs(a - b) < 2) continue;
    g.add_between(key(a), key(b), pose({u(rng), u(rng), u(rng)}, {u(rng) / 2, u(rng) / 2, u(rng) / 2}), info);
    ++added;
  }
  return g;
}

// Initial values from the odometry alone, the first pose at the truth.
void initialise_from_odometry_alone(PoseGraph& g, const Eigen::Isometry3d& first) {
  PoseGraph odometry = g;
  std::erase_if(odometry.factors, [](const Factor& f) { return f.kind != FactorKind::kOdometry; });
  odometry.poses[make_key(0, 0)] = first;
  ASSERT_TRUE(initialise_from_odometry(odometry));
  g.poses = odometry.poses;
}

// The largest position difference between two estimates of the same poses [m].
double max_difference(const PoseGraph& a, const PoseGraph& b) {
  double worst = 0;
  for (const auto& [k, T] : a.poses) worst = std::max(worst, (b.poses.at(k).translation() - T.translation()).norm());
  return worst;
}

// The least-squares solution of the graph without its wrong loops (the same noise), from odometry.
PoseGraph clean_optimum() {
  std::vector<Eigen::Isometry3d> truth;
  PoseGraph g = noisy_helix_with_wrong_loops(0, truth);
  initialise_from_odometry_alone(g, truth[0]);
  solve(g, SolverOptions{});
  return g;
}

constexpr int kWrong = 8;

TEST(Gnc, RejectsEveryWrongLoopAndKeepsEveryTrueOne) {
  std::vector<Eigen::Isometry3d> truth;
  PoseGraph g = noisy_helix_with_wrong_loops(kWrong, truth);
  initialise_from_odometry_alone(g, truth[0]);
  SolverOptions o;
  o.gnc.enabled = true;
  const SolveResult r = solve(g, o);
  ASSERT_FALSE(r.failed);
  EXPECT_TRUE(r.gnc_converged);
  ASSERT_EQ(r.weights.size(), g.factors.size());
  const size_t first_wrong = g.factors.size() - kWrong;
  for (size_t i = 0; i < g.factors.size(); ++i) {
    if (g.factors[i].kind == FactorKind::kOdometry) {
      EXPECT_EQ(r.weights[i], 1.0) << "odometry stays quadratic";
    } else if (i < first_wrong) {
      EXPECT_GT(r.weights[i], kGncAcceptedWeight) << "true loop " << i;
    } else {
      EXPECT_LT(r.weights[i], kGncAcceptedWeight) << "wrong loop " << i;
    }
  }
  EXPECT_LT(max_difference(g, clean_optimum()), 1e-6) << "the truncated optimum is the clean graph's";
}

// The same graph without GNC: least squares (and a Cauchy loss) bend towards the wrong loops.
TEST(Gnc, TheSameGraphWithoutGncIsPulledOffByTheWrongLoops) {
  for (double cauchy : {0.0, 1.0}) {
    std::vector<Eigen::Isometry3d> truth;
    PoseGraph g = noisy_helix_with_wrong_loops(kWrong, truth);
    initialise_from_odometry_alone(g, truth[0]);
    SolverOptions o;
    o.robust_loss_scale = cauchy;
    const SolveResult r = solve(g, o);
    EXPECT_TRUE(r.weights.empty());
    EXPECT_GT(max_difference(g, clean_optimum()), 0.1) << "Cauchy scale " << cauchy;
  }
}

// Without wrong loops GNC is least squares: every weight 1, the same solution.
TEST(Gnc, WithoutWrongLoopsItIsLeastSquares) {
  std::vector<Eigen::Isometry3d> truth;
  PoseGraph g = noisy_helix_with_wrong_loops(0, truth);
  initialise_from_odometry_alone(g, truth[0]);
  SolverOptions o;
  o.gnc.enabled = true;
  const SolveResult r = solve(g, o);
  for (double w : r.weights) EXPECT_EQ(w, 1.0);
  EXPECT_LT(max_difference(g, clean_optimum()), 1e-6);
}

}  // namespace
}  // namespace cdc::graph
