#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/objective.hpp"
#include "cdc/graph/solver.hpp"
#include "temp_dir.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

namespace cdc::graph {
namespace {

Eigen::Isometry3d pose(double x, double y, double z, double yaw, double pitch = 0, double roll = 0) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

// A helix of poses with odometry and loop closures between turns; exact measurements.
PoseGraph helix(int n, Eigen::Isometry3d* truth_out = nullptr, std::vector<Eigen::Isometry3d>* truth = nullptr) {
  (void)truth_out;
  PoseGraph g;
  std::vector<Eigen::Isometry3d> gt;
  for (int i = 0; i < n; ++i) {
    const double a = 0.3 * i;
    gt.push_back(pose(10 * std::cos(a), 10 * std::sin(a), 0.2 * i, a + M_PI / 2, 0.1 * std::sin(a), 0.05));
  }
  Matrix6d info = Matrix6d::Identity();
  info.topLeftCorner<3, 3>() *= 4.0;
  info.bottomRightCorner<3, 3>() *= 100.0;
  for (int i = 0; i + 1 < n; ++i) {
    g.add_between(make_key(0, static_cast<uint64_t>(i)), make_key(0, static_cast<uint64_t>(i + 1)),
                  gt[static_cast<size_t>(i)].inverse() * gt[static_cast<size_t>(i + 1)], info);
  }
  const int turn = 21;  // 0.3 * 21 ~ 2 pi: close to the pose one turn below
  for (int i = 0; i + turn < n; i += 3) {
    g.add_between(make_key(0, static_cast<uint64_t>(i)), make_key(0, static_cast<uint64_t>(i + turn)),
                  gt[static_cast<size_t>(i)].inverse() * gt[static_cast<size_t>(i + turn)], info);
  }
  for (int i = 0; i < n; ++i) {
    g.poses[make_key(0, static_cast<uint64_t>(i))] = gt[static_cast<size_t>(i)];
  }
  if (truth != nullptr) {
    *truth = gt;
  }
  return g;
}

TEST(SharedLoops, EachLoopIsDividedByTheMostLoopsAtEitherKeyframe) {
  PoseGraph g;
  const Matrix6d info = Matrix6d::Identity() * 60.0;
  for (uint64_t i = 0; i < 3; ++i) {
    g.add_between(make_key(0, i), make_key(0, i + 1), pose(1, 0, 0, 0), info);
  }
  // a1 takes part in three loops, b2 in two, the others in one.
  const std::vector<std::pair<uint64_t, uint64_t>> loops{{1, 1}, {1, 2}, {1, 3}, {2, 2}};
  for (const auto& [a, b] : loops) {
    g.add_between(make_key(0, a), make_key(1, b), pose(0, 2, 0, 0), info);
  }
  const std::map<Key, int> counts = loop_counts(g);
  EXPECT_EQ(counts.at(make_key(0, 1)), 3);
  EXPECT_EQ(counts.at(make_key(1, 2)), 2);
  EXPECT_EQ(counts.count(make_key(0, 0)), 0u) << "odometry is not counted";
  PoseGraph window;  // a part of the graph, counted over the whole
  window.factors = {g.factors[6]};
  share_loop_information(window, counts);
  share_loop_information(g);
  const std::vector<double> expected{60, 60, 60, 20, 20, 20, 30};
  ASSERT_EQ(g.factors.size(), expected.size());
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_DOUBLE_EQ(g.factors[i].information(0, 0), expected[i]) << "factor " << i;
    EXPECT_DOUBLE_EQ(g.factors[i].information(5, 5), expected[i]) << "factor " << i;
  }
  EXPECT_DOUBLE_EQ(window.factors[0].information(3, 3), 30);
}

TEST(SharedLoops, ABundleThroughOneBiasedCloudMovesTheRobotLessThanIndependentLoops) {
  // Robot 0 is known (prior); robot 1 drives beside it 2 m to the left. Eight loops all go through
  // robot 1's keyframe 5 and share its cloud's 0.3 m error along x; two loops at the ends are right.
  // Shared, the eight weigh as one against the two (about 0.3 / 3 m off, against 0.3 * 8 / 10 m if
  // robot 1 moved rigidly; its odometry spreads the pull: 0.12 against 0.22 m).
  auto build = [](bool share) {
    PoseGraph g;
    const Matrix6d odo = Matrix6d::Identity() * 400.0, loop = Matrix6d::Identity() * 25.0;
    for (uint32_t robot = 0; robot < 2; ++robot) {
      for (uint64_t i = 0; i < 10; ++i) {
        g.poses[make_key(robot, i)] = pose(static_cast<double>(i), 2.0 * robot, 0, 0);
        if (i > 0) {
          g.add_between(make_key(robot, i - 1), make_key(robot, i), pose(1, 0, 0, 0), odo);
        }
      }
    }
    g.add_prior(make_key(0, 0), pose(0, 0, 0, 0), Matrix6d::Identity() * 1e6);
    for (uint64_t i = 1; i < 9; ++i) {
      g.add_between(make_key(0, i), make_key(1, 5), pose(5.0 - static_cast<double>(i) + 0.3, 2, 0, 0), loop);
    }
    g.add_between(make_key(0, 0), make_key(1, 0), pose(0, 2, 0, 0), loop);
    g.add_between(make_key(0, 9), make_key(1, 9), pose(0, 2, 0, 0), loop);
    if (share) {
      share_loop_information(g);
    }
    SolverOptions o;
    solve(g, o);
    return (g.poses.at(make_key(1, 5)).translation() - Eigen::Vector3d(5, 2, 0)).norm();
  };
  const double independent = build(false), shared = build(true);
  std::printf("robot 1 keyframe 5 off by %.3f m (loops independent), %.3f m (shared)\n", independent, shared);
  EXPECT_GT(independent, 0.2);
  EXPECT_LT(shared, 0.6 * independent);
}

TEST(LevelledLoops, TiltInformationIsScaledAboutTheLevelAxesOfTheKeyframe) {
  PoseGraph g;
  g.poses[make_key(0, 0)] = pose(0, 0, 0, 0);
  g.poses[make_key(0, 1)] = pose(1, 0, 0, 0);
  g.poses[make_key(1, 0)] = pose(0, 2, 0, 0.7);          // level, turned: tilt axes still x and y
  g.poses[make_key(1, 1)] = pose(1, 2, 0, 0, M_PI / 2);  // pitched up 90 deg: up is its -x axis
  const Matrix6d info = Matrix6d::Identity() * 100.0;
  g.add_between(make_key(0, 0), make_key(0, 1), pose(1, 0, 0, 0), info);
  g.add_between(make_key(0, 0), make_key(1, 0), pose(0, 2, 0, 0.7), info);
  g.add_between(make_key(0, 1), make_key(1, 1), pose(0, 2, 0, 0, M_PI / 2), info);
  PoseGraph unchanged = g;
  level_loop_information(unchanged, 1.0);
  for (size_t i = 0; i < g.factors.size(); ++i) {
    EXPECT_TRUE(unchanged.factors[i].information.isApprox(info)) << "scale 1 changes nothing";
  }
  level_loop_information(g, 0.01);
  using Diag = Eigen::Matrix<double, 6, 1>;
  const std::vector<Diag> expected{(Diag() << 100, 100, 100, 100, 100, 100).finished(),  // odometry: untouched
                                   (Diag() << 100, 100, 100, 1, 1, 100).finished(),      // roll, pitch scaled
                                   (Diag() << 100, 100, 100, 100, 1, 1).finished()};     // about its y and z
  for (size_t i = 0; i < expected.size(); ++i) {
    EXPECT_LT((g.factors[i].information - Matrix6d(expected[i].asDiagonal())).norm(), 1e-9) << "factor " << i << ":\n"
                                                                                            << g.factors[i].information;
  }
}

TEST(LevelledLoops, LoopsWithABiasedTiltBendTheTrajectoryFarLess) {
  // A robot drives 30 m straight and level with exact odometry; loops span 10 keyframes and all
  // carry a 0.5 deg pitch error (registrations of sparse sweeps whose ground rings disagree).
  auto build = [](double tilt_scale) {
    PoseGraph g;
    Matrix6d odo = Matrix6d::Identity(), loop = Matrix6d::Identity();
    odo.topLeftCorner<3, 3>() *= 400.0;
    odo.bottomRightCorner<3, 3>() *= 1e4;  // 0.6 deg per step
    loop.topLeftCorner<3, 3>() *= 100.0;
    loop.bottomRightCorner<3, 3>() *= 1e4;
    const int n = 31;
    for (int i = 0; i < n; ++i) {
      g.poses[make_key(0, static_cast<uint64_t>(i))] = pose(i, 0, 0, 0);
      if (i > 0) {
        g.add_between(make_key(0, static_cast<uint64_t>(i - 1)), make_key(0, static_cast<uint64_t>(i)),
                      pose(1, 0, 0, 0), odo);
      }
    }
    g.add_prior(make_key(0, 0), pose(0, 0, 0, 0), Matrix6d::Identity() * 1e6);
    for (int i = 0; i + 10 < n; i += 2) {
      g.add_between(make_key(0, static_cast<uint64_t>(i)), make_key(0, static_cast<uint64_t>(i + 10)),
                    pose(10, 0, 0, 0, 0.5 * M_PI / 180), loop);
    }
    level_loop_information(g, tilt_scale);
    SolverOptions o;
    solve(g, o);
    double worst = 0;
    for (const auto& [k, T] : g.poses) {
      worst = std::max(worst, std::abs(T.translation().z()));
    }
    return worst;
  };
  const double plain = build(1.0), levelled = build(0.01);
  std::printf("largest height error: %.4f m (loops as measured), %.4f m (tilt x 0.01)\n", plain, levelled);
  EXPECT_GT(plain, 0.05);
  EXPECT_LT(levelled, 0.25 * plain);
}

TEST(Keys, RobotInTheTopByte) {
  const Key k = make_key(3, 12345);
  EXPECT_EQ(robot_of(k), 3u);
  EXPECT_EQ(index_of(k), 12345u);
  EXPECT_EQ(from_g2o_key((uint64_t{'c'} << 56) | 7), make_key(2, 7));
  EXPECT_EQ(from_g2o_key(42), 42u);
}

TEST(Objective, ZeroAtTheTruthAndWeightsAsSpecified) {
  PoseGraph g = helix(60);
  EXPECT_LT(full_information_cost(g), 1e-18);
  EXPECT_LT(sesync_objective(g), 1e-18);
  Factor f;
  f.information = Matrix6d::Identity();
  f.information.topLeftCorner<3, 3>() *= 4.0;        // tr(inv) = 3/4 -> tau = 4
  f.information.bottomRightCorner<3, 3>() *= 100.0;  // tr(inv) = 3/100 -> kappa = 50
  const IsotropicWeights w = isotropic_weights(f, 3);
  EXPECT_DOUBLE_EQ(w.tau, 4.0);
  EXPECT_DOUBLE_EQ(w.kappa, 50.0);
  // One perturbed pose: SE-Sync objective by hand for an isotropic single edge.
  PoseGraph two;
  two.add_between(0, 1, pose(1, 0, 0, 0), f.information);
  two.poses[0] = Eigen::Isometry3d::Identity();
  two.poses[1] = pose(1, 0.5, 0, 0.2);
  const double rot = (pose(0, 0, 0, 0.2).rotation() - Eigen::Matrix3d::Identity()).squaredNorm();  // 8 sin^2(0.1)
  EXPECT_NEAR(sesync_objective(two), 50.0 * rot + 4.0 * 0.25, 1e-12);
  EXPECT_NEAR(rot, 8 * std::pow(std::sin(0.1), 2), 1e-12);
  // Full information: t_err = (0, 0.5, 0), rotation residual 2 sin(0.1) about z.
  EXPECT_NEAR(full_information_cost(two), 4.0 * 0.25 + 100.0 * std::pow(2 * std::sin(0.1), 2), 1e-12);
}

TEST(Initialise, ChordalRecoversConsistentGraphExactly) {
  std::vector<Eigen::Isometry3d> gt;
  PoseGraph g = helix(80, nullptr, &gt);
  // Destroy every initial value but the anchor's.
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-3, 3);
  for (auto& [k, T] : g.poses) {
    if (k != make_key(0, 0)) {
      T = pose(u(rng) * 10, u(rng) * 10, u(rng), u(rng), u(rng) / 3, u(rng) / 3);
    }
  }
  ASSERT_TRUE(chordal_initialise(g));
  for (int i = 0; i < 80; ++i) {
    EXPECT_LT((g.poses.at(make_key(0, static_cast<uint64_t>(i))).matrix() - gt[static_cast<size_t>(i)].matrix()).norm(),
              1e-8)
        << i;
  }
}

TEST(Initialise, ChordalOnAGraphThatIsNotConnectedPlacesTheAnchorsPartAndSaysSo) {
  std::vector<Eigen::Isometry3d> gt;
  PoseGraph g = helix(40, nullptr, &gt);
  // A second robot joined to nothing of the first.
  g.add_between(make_key(1, 0), make_key(1, 1), pose(1, 0, 0, 0), Matrix6d::Identity());
  g.poses[make_key(1, 0)] = pose(50, 0, 0, 0);
  g.poses[make_key(1, 1)] = pose(70, 0, 0, 0);
  for (int i = 1; i < 40; ++i) g.poses[make_key(0, static_cast<uint64_t>(i))] = Eigen::Isometry3d::Identity();
  EXPECT_FALSE(chordal_initialise(g));
  for (int i = 0; i < 40; ++i) {
    EXPECT_LT((g.poses.at(make_key(0, static_cast<uint64_t>(i))).matrix() - gt[static_cast<size_t>(i)].matrix()).norm(),
              1e-8)
        << i;
  }
  EXPECT_EQ(g.poses.at(make_key(1, 1)).translation().x(), 70.0) << "the other part keeps its values";
}

TEST(Initialise, OdometryChainingFollowsTheMeasurements) {
  std::vector<Eigen::Isometry3d> gt;
  PoseGraph g = helix(30, nullptr, &gt);
  g.poses.clear();
  ASSERT_TRUE(initialise_from_odometry(g));
  ASSERT_EQ(g.poses.size(), 30u);
  // The anchor starts at identity; the chain reproduces the truth relative to pose 0.
  const Eigen::Isometry3d offset = gt[0].inverse();
  for (int i = 0; i < 30; ++i) {
    EXPECT_LT(
        (g.poses.at(make_key(0, static_cast<uint64_t>(i))).matrix() - (offset * gt[static_cast<size_t>(i)]).matrix())
            .norm(),
        1e-9);
  }
}

TEST(Solver, ChordalInitialisationEscapesTheLocalMinimumOfBadInitialValues) {
  // Consistent measurements (f* = 0) but initial values with large rotation errors, as from long
  // noisy odometry: LM from those values stalls above zero, chordal initialisation reaches f*.
  std::vector<Eigen::Isometry3d> gt;
  PoseGraph bad = helix(120, nullptr, &gt);
  std::mt19937 rng(9);
  std::normal_distribution<double> yaw(0.0, 1.0);
  Eigen::Isometry3d drift = Eigen::Isometry3d::Identity();
  for (int i = 1; i < 120; ++i) {
    const Eigen::Isometry3d step = gt[static_cast<size_t>(i - 1)].inverse() * gt[static_cast<size_t>(i)];
    drift = drift * step * pose(0, 0, 0, yaw(rng));  // odometry with a heavy yaw error per step
    bad.poses[make_key(0, static_cast<uint64_t>(i))] = gt[0] * drift;
  }
  PoseGraph from_odometry = bad;
  SolverOptions opts;
  opts.objective = Objective::kSeSync;
  opts.max_iterations = 1000;
  const SolveResult r_odo = solve(from_odometry, opts);
  PoseGraph ours = bad;
  ASSERT_TRUE(chordal_initialise(ours));
  const SolveResult r_ours = solve(ours, opts);
  std::printf("LM from odometry: f = %.6g after %d iterations; chordal + LM: f = %.3g after %d iterations\n",
              r_odo.final_cost, r_odo.iterations, r_ours.final_cost, r_ours.iterations);
  EXPECT_LT(r_ours.final_cost, 1e-10);
  EXPECT_GT(r_odo.final_cost, 1.0) << "the constructed case is meant to trap LM from odometry";
  EXPECT_TRUE(r_odo.converged) << "LM should stop in a local minimum, not at the iteration limit: " << r_odo.message;
}

TEST(Solver, RecoversTruthFromNoisyInitialValuesWithBothObjectives) {
  std::vector<Eigen::Isometry3d> gt;
  for (Objective o : {Objective::kFullInformation, Objective::kSeSync}) {
    PoseGraph g = helix(60, nullptr, &gt);
    std::mt19937 rng(3);
    std::normal_distribution<double> n(0.0, 0.05);
    for (auto& [k, T] : g.poses) {
      if (k != make_key(0, 0)) {
        T = T * pose(n(rng), n(rng), n(rng), n(rng), n(rng), n(rng));
      }
    }
    SolverOptions opts;
    opts.objective = o;
    const SolveResult r = solve(g, opts);
    EXPECT_TRUE(r.converged) << r.message;
    EXPECT_GT(r.initial_cost, 1.0);
    EXPECT_LT(r.final_cost, 1e-12);
    for (int i = 0; i < 60; ++i) {
      EXPECT_LT(
          (g.poses.at(make_key(0, static_cast<uint64_t>(i))).translation() - gt[static_cast<size_t>(i)].translation())
              .norm(),
          1e-6);
    }
  }
}

TEST(Solver, PriorAnchorsTheGraphAndFixedKeysStay) {
  PoseGraph g;
  Matrix6d info = Matrix6d::Identity();
  g.add_prior(0, pose(5, 5, 0, 1.0), info * 1e6);
  g.add_between(0, 1, pose(1, 0, 0, 0), info);
  g.poses[0] = Eigen::Isometry3d::Identity();
  g.poses[1] = Eigen::Isometry3d::Identity();
  solve(g, SolverOptions{});
  EXPECT_LT((g.poses.at(0).matrix() - pose(5, 5, 0, 1.0).matrix()).norm(), 1e-6);
  EXPECT_LT((g.poses.at(1).matrix() - (pose(5, 5, 0, 1.0) * pose(1, 0, 0, 0)).matrix()).norm(), 1e-6);

  PoseGraph h;
  h.add_between(0, 1, pose(1, 0, 0, 0), info);
  h.poses[0] = pose(0, 0, 0, 0);
  h.poses[1] = pose(3, 0, 0, 0);
  solve(h, SolverOptions{}, {1});
  EXPECT_LT((h.poses.at(1).translation() - Eigen::Vector3d(3, 0, 0)).norm(), 1e-12);
  EXPECT_LT((h.poses.at(0).translation() - Eigen::Vector3d(2, 0, 0)).norm(), 1e-6);
}

class G2oFiles : public test::TempDirTest {
 protected:
  G2oFiles() : TempDirTest("g2o") {}
};

TEST_F(G2oFiles, RoundTrip3D) {
  PoseGraph g = helix(40);
  write_g2o(path("h.g2o"), g);
  const PoseGraph r = read_g2o(path("h.g2o"));
  ASSERT_EQ(r.poses.size(), g.poses.size());
  ASSERT_EQ(r.factors.size(), g.factors.size());
  for (const auto& [k, T] : g.poses) {
    EXPECT_LT((r.poses.at(k).matrix() - T.matrix()).norm(), 1e-12);
  }
  for (size_t i = 0; i < g.factors.size(); ++i) {
    EXPECT_EQ(r.factors[i].a, g.factors[i].a);
    EXPECT_EQ(r.factors[i].kind, g.factors[i].kind);
    EXPECT_LT((r.factors[i].measurement.matrix() - g.factors[i].measurement.matrix()).norm(), 1e-12);
    EXPECT_LT((r.factors[i].information - g.factors[i].information).norm(), 1e-9);
  }
}

TEST_F(G2oFiles, Planar2DIsLiftedAndRoundTrips) {
  std::ofstream(path("p.g2o")) << "VERTEX_SE2 0 0 0 0\nVERTEX_SE2 1 1 0 0.5\n"
                                  "EDGE_SE2 0 1 1 0 0.5 10 1 2 20 3 30\n";
  const PoseGraph g = read_g2o(path("p.g2o"));
  EXPECT_EQ(g.dimension, 2);
  ASSERT_EQ(g.factors.size(), 1u);
  const Matrix6d& I = g.factors[0].information;
  EXPECT_DOUBLE_EQ(I(0, 0), 10);
  EXPECT_DOUBLE_EQ(I(0, 1), 1);
  EXPECT_DOUBLE_EQ(I(0, 5), 2);
  EXPECT_DOUBLE_EQ(I(1, 5), 3);
  EXPECT_DOUBLE_EQ(I(5, 5), 30);
  EXPECT_DOUBLE_EQ(I(2, 2), kPlanarLiftInformation);
  write_g2o(path("q.g2o"), g);
  const PoseGraph r = read_g2o(path("q.g2o"));
  EXPECT_EQ(r.dimension, 2);
  EXPECT_LT((r.poses.at(1).matrix() - g.poses.at(1).matrix()).norm(), 1e-12);
  EXPECT_LT((r.factors[0].information - I).norm(), 1e-9);
}

TEST_F(G2oFiles, ErrorsNameFileAndLine) {
  std::ofstream(path("bad.g2o")) << "VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1\nEDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 1 0 0\n";
  try {
    read_g2o(path("bad.g2o"));
    FAIL();
  } catch (const G2oError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("bad.g2o:2: missing information entry"));
  }
  std::ofstream(path("tag.g2o")) << "VERTEX_XY 0 1 2\n";
  EXPECT_THROW(read_g2o(path("tag.g2o")), G2oError);
  std::ofstream(path("nan.g2o")) << "VERTEX_SE3:QUAT 0 nan 0 0 0 0 0 1\n";
  EXPECT_THROW(read_g2o(path("nan.g2o")), G2oError);
  std::ofstream(path("pd.g2o")) << "EDGE_SE2 0 1 1 0 0 -1 0 0 1 0 1\n";
  EXPECT_THAT([&] { read_g2o(path("pd.g2o")); },
              ::testing::ThrowsMessage<G2oError>(::testing::HasSubstr("positive definite")));
  EXPECT_THROW(read_g2o(path("none.g2o")), G2oError);
}

// A graph that declares vertices declares each once and every vertex its edges use; one that declares none is
// legitimate and its poses are counted as implicit.
TEST_F(G2oFiles, VerticesAreDeclaredOnceAndForEveryEdgeOrNotAtAll) {
  const std::string v = "VERTEX_SE3:QUAT ", q = " 0 0 0 1", e = "EDGE_SE3:QUAT ";
  const std::string info = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  std::ofstream(path("dup.g2o")) << v << "0 0 0 0" << q << "\n"
                                 << v << "1 1 0 0" << q << "\n"
                                 << v << "1 2 0 0" << q << "\n"
                                 << e << "0 1 1 0 0" << q << info;
  EXPECT_THAT([&] { read_g2o(path("dup.g2o")); },
              ::testing::ThrowsMessage<G2oError>(
                  ::testing::HasSubstr("dup.g2o:3: vertex 1 declared again with a different pose (first on line 2)")));
  std::ofstream(path("same.g2o")) << v << "0 0 0 0" << q << "\n"
                                  << v << "1 1 0 0" << q << "\n"
                                  << v << "1 1 0 0" << q << "\n"
                                  << e << "0 1 1 0 0" << q << info;
  EXPECT_EQ(read_g2o(path("same.g2o")).poses.size(), 2u);  // the same pose twice: harmless
  std::ofstream(path("undeclared.g2o")) << v << "0 0 0 0" << q << "\n"
                                        << v << "1 1 0 0" << q << "\n"
                                        << e << "0 1 1 0 0" << q << info << e << "1 2 1 0 0" << q << info;
  EXPECT_THAT([&] { read_g2o(path("undeclared.g2o")); },
              ::testing::ThrowsMessage<G2oError>(
                  ::testing::HasSubstr("edges name 1 vertices no VERTEX line declares (2 the first)")));
  std::ofstream(path("edges.g2o")) << e << "0 1 1 0 0" << q << info << e << "1 2 1 0 0" << q << info;
  G2oReadReport report;
  G2oReadOptions options;
  options.report = &report;
  const PoseGraph g = read_g2o(path("edges.g2o"), options);
  EXPECT_EQ(g.factors.size(), 2u);
  EXPECT_EQ(report.vertices, 0u);
  EXPECT_EQ(report.implicit_vertices, 3u);
}

// Ids whose top byte names no robot a..z go back to a file as they came, even beside GTSAM symbols.
TEST_F(G2oFiles, IdsOutsideTheSymbolLettersAreWrittenBackAsRead) {
  const uint64_t a0 = uint64_t{'a'} << 56, big = (uint64_t{'A'} << 56) | 3;
  std::ofstream(path("mixed.g2o")) << "VERTEX_SE3:QUAT " << a0 << " 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT " << big
                                   << " 1 0 0 0 0 0 1\nEDGE_SE3:QUAT " << a0 << ' ' << big
                                   << " 1 0 0 0 0 0 1 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  const PoseGraph g = read_g2o(path("mixed.g2o"));
  ASSERT_TRUE(g.symbol_keys);
  EXPECT_EQ(to_g2o_key(g, g.factors[0].a), a0);
  EXPECT_EQ(to_g2o_key(g, g.factors[0].b), big);
  std::ofstream(path("collide.g2o")) << "VERTEX_SE3:QUAT " << a0 << " 0 0 0 0 0 0 1\nVERTEX_SE3:QUAT 5 1 0 0 0 0 0 1\n";
  EXPECT_THAT([&] { read_g2o(path("collide.g2o")); },
              ::testing::ThrowsMessage<G2oError>(::testing::HasSubstr("mixes GTSAM symbol ids")));
}

// A 6x6 information that is not positive definite (a strong translation-rotation coupling) whose
// isotropic weights are positive: refused by default, read for SE-Sync's objective.
TEST_F(G2oFiles, IndefiniteInformationWithPositiveIsotropicWeightsIsReadForSeSync) {
  const std::string q = " 0 0 0 1";
  // Upper triangle: diag 1, coupling (tx, rx) = 5: eigenvalues 1 +- 5, one negative.
  const std::string info = " 1 0 0 5 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  std::ofstream(path("indef.g2o")) << "EDGE_SE3:QUAT 0 1 1 0 0" << q << info;
  EXPECT_THAT([&] { read_g2o(path("indef.g2o")); },
              ::testing::ThrowsMessage<G2oError>(::testing::HasSubstr("not positive definite")));
  G2oReadOptions options;
  options.isotropic_information = true;
  G2oReadReport report;
  options.report = &report;
  const PoseGraph g = read_g2o(path("indef.g2o"), options);
  ASSERT_EQ(g.factors.size(), 1u);
  EXPECT_EQ(report.indefinite_information, 1u);
  const IsotropicWeights w = isotropic_weights(g.factors[0], 3);
  EXPECT_DOUBLE_EQ(w.tau, 1.0);
  EXPECT_DOUBLE_EQ(w.kappa, 0.5);
  std::ofstream(path("zero.g2o")) << "EDGE_SE3:QUAT 0 1 1 0 0" << q << " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 0 0 0 0 0 0\n";
  EXPECT_THAT([&] { read_g2o(path("zero.g2o"), options); },
              ::testing::ThrowsMessage<G2oError>(::testing::HasSubstr("no positive isotropic weights")));
}

// Two measurements between the same two poses are two factors, in one file or in two; only an edge a
// second robot's file lists alike (the same measurement) is kept once.
TEST_F(G2oFiles, ParallelEdgesAreKeptAndOnlyIdenticalListingsMerge) {
  const uint64_t a0 = uint64_t{'a'} << 56, b0 = uint64_t{'b'} << 56;
  const std::string q = " 0 0 0 1", info = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  std::ofstream(path("par.g2o")) << "EDGE_SE3:QUAT 0 5 1 0 0" << q << info << "EDGE_SE3:QUAT 0 5 1.1 0 0" << q << info;
  G2oReadReport report;
  G2oReadOptions options;
  options.report = &report;
  EXPECT_EQ(read_g2o(path("par.g2o"), options).factors.size(), 2u);
  EXPECT_EQ(report.parallel_edges, 1u);
  std::filesystem::create_directories(path("robots"));
  std::ofstream(path("robots/a.g2o")) << "EDGE_SE3:QUAT " << a0 << ' ' << a0 + 1 << " 1 0 0" << q << info
                                      << "EDGE_SE3:QUAT " << a0 << ' ' << b0 << " 2 0 0" << q << info;
  std::ofstream(path("robots/b.g2o")) << "EDGE_SE3:QUAT " << b0 << ' ' << b0 + 1 << " 1 0 0" << q << info
                                      << "EDGE_SE3:QUAT " << a0 << ' ' << b0 << " 2 0 0" << q << info
                                      << "EDGE_SE3:QUAT " << a0 << ' ' << b0 << " 2.5 0 0" << q << info;
  const PoseGraph g = read_g2o_folder(path("robots"), options);
  EXPECT_EQ(g.factors.size(), 4u);  // two odometry, the shared loop once, its parallel loop
  EXPECT_EQ(report.duplicate_edges, 1u);
  EXPECT_EQ(report.parallel_edges, 1u);
}

// In a multi-robot folder every id names its robot; a file with plain ids is refused, not merged into robot 0.
TEST_F(G2oFiles, AFolderFileWithoutRobotLettersIsRefused) {
  const uint64_t a0 = uint64_t{'a'} << 56;
  const std::string q = " 0 0 0 1", info = " 1 0 0 0 0 0 1 0 0 0 0 1 0 0 0 1 0 0 1 0 1\n";
  std::filesystem::create_directories(path("mixed_robots"));
  std::ofstream(path("mixed_robots/a.g2o")) << "EDGE_SE3:QUAT " << a0 << ' ' << a0 + 1 << " 1 0 0" << q << info;
  std::ofstream(path("mixed_robots/plain.g2o")) << "EDGE_SE3:QUAT 0 1 1 0 0" << q << info;
  G2oReadOptions lenient;
  lenient.skip_malformed = true;  // refusing the file is not a line to skip
  EXPECT_THAT([&] { read_g2o_folder(path("mixed_robots"), lenient); },
              ::testing::ThrowsMessage<G2oError>(::testing::AllOf(::testing::HasSubstr("plain.g2o:1: id 0"),
                                                                  ::testing::HasSubstr("carries no robot letter"))));
}

}  // namespace
}  // namespace cdc::graph
