// Graduated non-convexity on a small synthetic graph with wrong loop closures.
#include "cdc/geometry/se3.hpp"
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
  T.linear() = geometry::so3_exp(rotation_vector);
  T.translation() = t;
  return T;
}

// Three turns of a helix (radius 5 m, 20 poses a turn), odometry and loops one turn apart. Loops
// carry information of 0.02 m and 0.01 rad and noise loop_noise times that; odometry carries
// information odometry_sigma times theirs and noise that matches it. Then `wrong` loops between
// random poses: with wrong_offset 0 at random relative poses (metres off), otherwise the true
// relative pose moved by wrong_offset [m] in a random direction. The truth is returned in `truth`.
struct Helix {
  int wrong = 0;
  double loop_noise = 1.0;
  double odometry_sigma = 1.0;
  double wrong_offset = 0.0;
};

Matrix6d information(double sigma_t, double sigma_r) {
  Matrix6d info = Matrix6d::Identity();
  info.topLeftCorner<3, 3>() *= 1.0 / (sigma_t * sigma_t);
  info.bottomRightCorner<3, 3>() *= 1.0 / (sigma_r * sigma_r);
  return info;
}

PoseGraph noisy_helix(const Helix& h, std::vector<Eigen::Isometry3d>& truth) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  const int turn = 20, n = 3 * turn;
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / turn;
    truth.push_back(pose({5 * std::cos(a), 5 * std::sin(a), 0.3 * i}, {0, 0, a + M_PI / 2}));
  }
  auto noisy = [&](const Eigen::Isometry3d& T, double st, double sr) {
    return T * pose({st * n01(rng), st * n01(rng), st * n01(rng)}, {sr * n01(rng), sr * n01(rng), sr * n01(rng)});
  };
  const double so = h.odometry_sigma, sl = h.loop_noise;
  PoseGraph g;
  auto key = [](int i) { return make_key(0, static_cast<uint64_t>(i)); };
  auto rel = [&](int i, int j) { return truth[static_cast<size_t>(i)].inverse() * truth[static_cast<size_t>(j)]; };
  for (int i = 0; i + 1 < n; ++i) {
    g.add_between(key(i), key(i + 1), noisy(rel(i, i + 1), 0.02 * so, 0.01 * so), information(0.02 * so, 0.01 * so));
  }
  for (int i = 0; i + turn < n; i += 2) {
    g.add_between(key(i), key(i + turn), noisy(rel(i, i + turn), 0.02 * sl, 0.01 * sl), information(0.02, 0.01));
  }
  std::uniform_int_distribution<int> pick(0, n - 1);
  std::uniform_real_distribution<double> u(-4.0, 4.0);
  for (int added = 0; added < h.wrong;) {
    const int a = pick(rng), b = pick(rng);
    if (std::abs(a - b) < 2) continue;
    const Eigen::Isometry3d random = pose({u(rng), u(rng), u(rng)}, {u(rng) / 2, u(rng) / 2, u(rng) / 2});
    const Eigen::Vector3d direction = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)).normalized();
    const Eigen::Isometry3d nearly = rel(a, b) * pose(h.wrong_offset * direction, {0, 0, 0});
    g.add_between(key(a), key(b), h.wrong_offset == 0.0 ? random : nearly, information(0.02, 0.01));
    ++added;
  }
  return g;
}

PoseGraph noisy_helix_with_wrong_loops(int wrong, std::vector<Eigen::Isometry3d>& truth) {
  Helix h;
  h.wrong = wrong;
  return noisy_helix(h, truth);
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

// Loops whose information is 20 times more pessimistic than their noise (s 400 times smaller than it
// says) on stiff odometry, and wrong loops 7.5 cm off: within the default threshold (s = 14 < 16.81),
// so GNC keeps them; scaled to the accepted loops' median residual, the threshold rejects them.
TEST(Gnc, ACalibratedThresholdRejectsWrongLoopsThatPessimisticInformationHides) {
  std::vector<Eigen::Isometry3d> truth;
  Helix h;
  h.wrong = 3;
  h.loop_noise = 0.05;
  h.odometry_sigma = 0.001;  // odometry so stiff that its drift adds little to the loops' residuals
  h.wrong_offset = 0.075;
  const PoseGraph corrupted = noisy_helix(h, truth);
  const size_t first_wrong = corrupted.factors.size() - static_cast<size_t>(h.wrong);
  auto solve_with = [&](bool calibrate, size_t& wrong_accepted, size_t& true_rejected) {
    PoseGraph g = corrupted;
    initialise_from_odometry_alone(g, truth[0]);
    SolverOptions o;
    o.gnc.enabled = true;
    o.gnc.calibrate_threshold = calibrate;
    const SolveResult r = solve(g, o);
    wrong_accepted = true_rejected = 0;

    for (size_t i = 0; i < g.factors.size(); ++i) {
      if (g.factors[i].kind != FactorKind::kLoop) continue;
      const bool accepted = r.weights[i] > kGncAcceptedWeight;
      wrong_accepted += i >= first_wrong && accepted ? 1u : 0u;
      true_rejected += i < first_wrong && !accepted ? 1u : 0u;
    }
    return r;
  };
  size_t wrong_accepted = 0, true_rejected = 0;
  EXPECT_EQ(solve_with(false, wrong_accepted, true_rejected).gnc_threshold, GncOptions{}.inlier_threshold);
  EXPECT_GT(wrong_accepted, 0u) << "the default threshold keeps loops its information cannot tell apart";
  const SolveResult r = solve_with(true, wrong_accepted, true_rejected);
  EXPECT_LT(r.gnc_threshold, 0.5 * GncOptions{}.inlier_threshold);
  EXPECT_EQ(wrong_accepted, 0u);
  EXPECT_LE(true_rejected, 1u);
}

}  // namespace
}  // namespace cdc::graph
