#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/alignment.hpp"
#include "cdc/geometry/se3.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace cdc::geometry {
namespace {

constexpr double kDeg = M_PI / 180.0;

Eigen::Isometry3d translation(double x, double y, double z) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, z);
  return T;
}

Poses straight_line(size_t n, double step) {
  Poses p;
  for (size_t i = 0; i < n; ++i) {
    p.push_back(translation(step * static_cast<double>(i), 0, 0));
  }
  return p;
}

// 40 points drawn uniformly from the cube [-50, 50]^3 with this seed.
Eigen::Matrix3Xd random_points(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-50, 50);
  Eigen::Matrix3Xd points(3, 40);
  for (int i = 0; i < 40; ++i) {
    points.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  return points;
}

TEST(Alignment, RecoversKnownSe3Exactly) {
  const Eigen::Matrix3Xd src = random_points(11);
  const Eigen::Matrix3d R = from_rpy(0.3, -0.2, 2.0);
  const Eigen::Vector3d t(5, -7, 1.5);
  const Eigen::Matrix3Xd dst = (R * src).colwise() + t;
  const Alignment a = align_umeyama(src, dst, false);
  ASSERT_TRUE(a.ok);
  EXPECT_LT((a.T_dst_src.rotation() - R).norm(), 1e-9);
  EXPECT_LT((a.T_dst_src.translation() - t).norm(), 1e-9);
  EXPECT_DOUBLE_EQ(a.scale, 1.0);
}

TEST(Alignment, RecoversKnownSim3Exactly) {
  const Eigen::Matrix3Xd src = random_points(12);
  const Eigen::Matrix3d R = from_rpy(-1.0, 0.4, -2.5);
  const Eigen::Vector3d t(-3, 2, 10);
  const double s = 0.8;
  const Eigen::Matrix3Xd dst = ((s * R) * src).colwise() + t;
  const Alignment a = align_umeyama(src, dst, true);
  ASSERT_TRUE(a.ok);
  EXPECT_NEAR(a.scale, s, 1e-12);
  EXPECT_LT((a.T_dst_src.rotation() - R).norm(), 1e-9);
  EXPECT_LT((a.T_dst_src.translation() - t).norm(), 1e-9);
}

TEST(Alignment, DegenerateInputIsReported) {
  Eigen::Matrix3Xd line(3, 5);
  for (int i = 0; i < 5; ++i) {
    line.col(i) = Eigen::Vector3d(i, 0, 0);
  }
  EXPECT_FALSE(align_umeyama(line, line, false).ok);
  EXPECT_FALSE(align_umeyama(Eigen::Matrix3Xd(3, 0), Eigen::Matrix3Xd(3, 0), false).ok);
}

TEST(Alignment, PosesOfAStraightTrajectoryGiveTheFullTransform) {
  // Positions on a line leave the turn about it open; the orientations fix it.
  const Eigen::Isometry3d T = Eigen::Translation3d(4, -2, 0.7) * Eigen::Isometry3d(from_rpy(0.05, -0.03, 1.2));
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> pairs;
  for (int i = 0; i < 30; ++i) {
    const Eigen::Isometry3d a = Eigen::Translation3d(2.0 * i, 0, 0) * Eigen::Isometry3d(from_rpy(0, 0, 0.01 * i));
    pairs.emplace_back(a, T * a);
  }
  const Alignment al = align_poses(pairs, 1.0);
  ASSERT_TRUE(al.ok);
  EXPECT_LT((al.T_dst_src.matrix() - T.matrix()).norm(), 1e-9);
  // One pair: exactly b * a^-1.
  const Alignment one = align_poses({pairs[7]}, 1.0);
  ASSERT_TRUE(one.ok);
  EXPECT_LT((one.T_dst_src.matrix() - T.matrix()).norm(), 1e-9);
  EXPECT_FALSE(align_poses({}, 1.0).ok);
  EXPECT_FALSE(align_poses(pairs, 0.0).ok);
}

TEST(Alignment, StreamedPosesGiveTheFitOfAllTheirPoints) {
  // Far from the origin and noisy, so that the sums' cancellation would show: the streamed fit equals
  // Umeyama's over the same points (positions and the three axis points of each pose).
  const Eigen::Isometry3d T = Eigen::Translation3d(-300, 850, 12) * Eigen::Isometry3d(from_rpy(0.02, 0.04, -2.1));
  PoseAligner aligner(0.5);
  Eigen::Matrix3Xd src(3, 4 * 200), dst(3, 4 * 200);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Isometry3d a = Eigen::Translation3d(1000 + 3.0 * i, -500 + 0.02 * i * i, 0.1 * std::sin(i)) *
                                Eigen::Isometry3d(from_rpy(0.01 * std::cos(i), 0, 0.03 * i));
    const Eigen::Isometry3d b = Eigen::Translation3d(0.01 * std::sin(3 * i), 0.02 * std::cos(i), 0) * T * a;
    aligner.add(a, b);
    for (int k = 0; k < 4; ++k) {
      const Eigen::Vector3d arm =
          k == 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(0.5 * Eigen::Vector3d::Unit(k - 1));
      src.col(4 * i + k) = a * arm;
      dst.col(4 * i + k) = b * arm;
    }
  }
  EXPECT_EQ(aligner.pairs(), 200u);
  const Alignment streamed = aligner.solve();
  const Alignment direct = align_umeyama(src, dst, false);
  ASSERT_TRUE(streamed.ok);
  ASSERT_TRUE(direct.ok);
  EXPECT_LT((streamed.T_dst_src.matrix() - direct.T_dst_src.matrix()).norm(), 1e-6);
  EXPECT_LT((streamed.T_dst_src.matrix() - T.matrix()).norm(), 0.05);
  EXPECT_FALSE(PoseAligner().solve().ok);
}

TEST(Alignment, PosesFitTheWholeTrajectoryNotItsFirstPose) {
  // b bends away from a towards its end (drift corrected): the fit spreads the difference over the
  // trajectory instead of holding the first pose and swinging the far end.
  std::vector<std::pair<Eigen::Isometry3d, Eigen::Isometry3d>> pairs;
  for (int i = 0; i < 50; ++i) {
    const Eigen::Isometry3d a(Eigen::Translation3d(2.0 * i, 0, 0));
    const Eigen::Isometry3d b(Eigen::Translation3d(2.0 * i, 0, 0.001 * i * i));
    pairs.emplace_back(a, b);
  }
  const Alignment al = align_poses(pairs, 1.0);
  ASSERT_TRUE(al.ok);
  double worst_fit = 0, worst_first = 0;
  const Eigen::Isometry3d first = pairs.front().second * pairs.front().first.inverse();
  for (const auto& [a, b] : pairs) {
    worst_fit = std::max(worst_fit, ((al.T_dst_src * a).translation() - b.translation()).norm());
    worst_first = std::max(worst_first, ((first * a).translation() - b.translation()).norm());
  }
  EXPECT_NEAR(worst_first, 0.001 * 49 * 49, 1e-9);
  EXPECT_LT(worst_fit, 0.5 * worst_first);
}

TEST(Ate, ZeroForRigidlyMovedTrajectoryAfterSe3Alignment) {
  Poses gt;
  for (int i = 0; i < 100; ++i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = from_rpy(0, 0, 0.05 * i);
    T.translation() = Eigen::Vector3d(10 * std::cos(0.05 * i), 10 * std::sin(0.05 * i), 0.01 * i);
    gt.push_back(T);
  }
  Eigen::Isometry3d M = Eigen::Isometry3d::Identity();
  M.linear() = from_rpy(0.1, 0.2, 0.3);
  M.translation() = Eigen::Vector3d(100, -4, 2);
  Poses est;
  for (const auto& g : gt) {
    est.push_back(M * g);
  }
  const AteResult ate = compute_ate(est, gt, AlignMode::kSE3);
  EXPECT_LT(ate.translation.rmse, 1e-9);
  EXPECT_LT(ate.rotation_deg.max, 1e-6);
  EXPECT_GT(compute_ate(est, gt, AlignMode::kNone).translation.rmse, 1.0);
}

TEST(Ate, HandComputedWithoutAlignment) {
  const Poses gt = straight_line(4, 1.0);
  Poses est = gt;
  est[0].translation() += Eigen::Vector3d(0.1, 0, 0);
  est[1].translation() += Eigen::Vector3d(0, 0.2, 0);
  est[2].translation() += Eigen::Vector3d(0, 0, 0.3);
  const AteResult ate = compute_ate(est, gt, AlignMode::kNone);
  EXPECT_NEAR(ate.translation.rmse, std::sqrt((0.01 + 0.04 + 0.09) / 4.0), 1e-12);
  EXPECT_NEAR(ate.translation.mean, 0.15, 1e-12);
  EXPECT_NEAR(ate.translation.max, 0.3, 1e-12);
  EXPECT_NEAR(ate.translation.min, 0.0, 1e-12);
  EXPECT_NEAR(ate.translation.median, 0.15, 1e-12);
  EXPECT_EQ(ate.translation.count, 4u);
}

TEST(Ate, Sim3RemovesScaleError) {
  const Poses gt = [] {
    Poses p;
    for (int i = 0; i < 50; ++i) {
      p.push_back(translation(i, std::sin(0.3 * i) * 5, 0.1 * i));
    }
    return p;
  }();
  Poses est;
  for (const auto& g : gt) {
    est.push_back(translation(1.05 * g.translation().x(), 1.05 * g.translation().y(), 1.05 * g.translation().z()));
  }
  EXPECT_GT(compute_ate(est, gt, AlignMode::kSE3).translation.rmse, 0.1);
  const AteResult sim = compute_ate(est, gt, AlignMode::kSim3);
  EXPECT_LT(sim.translation.rmse, 1e-9);
  EXPECT_NEAR(sim.alignment.scale, 1.0 / 1.05, 1e-12);
}

TEST(Rpe, HandComputedTranslation) {
  const Poses gt = straight_line(5, 1.0);
  Poses est = gt;
  est[2].translation().y() += 0.5;
  const RpeResult r = compute_rpe_frames(est, gt, 1);
  ASSERT_EQ(r.translation.count, 4u);
  EXPECT_NEAR(r.translation.rmse, std::sqrt(0.125), 1e-12);
  EXPECT_NEAR(r.translation.mean, 0.25, 1e-12);
  EXPECT_NEAR(r.translation.max, 0.5, 1e-12);
  EXPECT_NEAR(r.rotation_deg.max, 0.0, 1e-12);
}

TEST(Rpe, HandComputedRotation) {
  const Poses gt = straight_line(5, 1.0);
  Poses est = gt;
  est[2].linear() = from_rpy(0, 0, 10 * kDeg);
  const RpeResult r = compute_rpe_frames(est, gt, 1);
  // Pairs (1,2) and (2,3) see 10 deg; (2,3) also sees the unit step turned by 10 deg.
  EXPECT_NEAR(r.rotation_deg.max, 10.0, 1e-9);
  EXPECT_NEAR(r.rotation_deg.mean, 5.0, 1e-9);
  EXPECT_NEAR(r.translation.max, 2.0 * std::sin(5 * kDeg), 1e-12);
}

TEST(Rpe, PerDistancePairs) {
  const Poses gt = straight_line(101, 0.5);  // 50 m
  Poses est;
  for (size_t i = 0; i < gt.size(); ++i) {
    est.push_back(translation(0.5 * 1.02 * static_cast<double>(i), 0, 0));  // 2 % scale error
  }
  const RpeResult r = compute_rpe_distance(est, gt, 10.0);
  EXPECT_EQ(r.translation.count, 81u);  // starts 0..80 reach 10 m within the trajectory
  EXPECT_NEAR(r.translation.mean, 0.2, 1e-9);
  EXPECT_EQ(r.delta, "10 m");
}

TEST(KittiDrift, ScaleErrorGivesItsPercentage) {
  const Poses gt = straight_line(1000, 1.0);
  Poses est;
  for (size_t i = 0; i < gt.size(); ++i) {
    est.push_back(translation(1.01 * static_cast<double>(i), 0, 0));
  }
  const KittiDrift d = compute_kitti_drift(est, gt);
  EXPECT_EQ(d.segments, 440u);  // 90 + 80 + ... + 20 segment starts for 100..800 m
  EXPECT_NEAR(d.translation_pct, 1.0, 1e-9);
  EXPECT_NEAR(d.rotation_deg_per_100m, 0.0, 1e-9);
}

TEST(KittiDrift, ConstantYawDriftGivesItsRate) {
  // Ground truth drives straight; the estimate turns by omega per metre.
  const double omega = 0.5 * kDeg / 100.0;  // 0.5 deg / 100 m
  const Poses gt = straight_line(1000, 1.0);
  Poses est{Eigen::Isometry3d::Identity()};
  Eigen::Isometry3d step = translation(1, 0, 0);
  step.linear() = from_rpy(0, 0, omega);
  for (size_t i = 1; i < gt.size(); ++i) {
    est.push_back(est.back() * step);
  }
  const KittiDrift d = compute_kitti_drift(est, gt);
  EXPECT_NEAR(d.rotation_deg_per_100m, 0.5, 1e-9);
  // Translation: over L steps the estimate reaches sum_m R(m omega) e1 instead of L e1.
  double t_sum = 0.0;
  size_t count = 0;
  for (int len = 100; len <= 800; len += 100) {
    Eigen::Vector2d p(0, 0);
    for (int m = 0; m < len; ++m) {
      p += Eigen::Vector2d(std::cos(m * omega), std::sin(m * omega));
    }
    const size_t starts = static_cast<size_t>((999 - len) / 10 + 1);
    t_sum += static_cast<double>(starts) * (p - Eigen::Vector2d(len, 0)).norm() / len;
    count += starts;
  }
  EXPECT_EQ(d.segments, count);
  EXPECT_NEAR(d.translation_pct, 100.0 * t_sum / static_cast<double>(count), 1e-9);
}

TEST(KittiDrift, ShortTrajectoryHasNoSegments) {
  const Poses gt = straight_line(50, 1.0);
  EXPECT_EQ(compute_kitti_drift(gt, gt).segments, 0u);
}

TEST(Stats, MedianAndStd) {
  const ErrorStats s = compute_stats({1, 2, 3, 4});
  EXPECT_DOUBLE_EQ(s.median, 2.5);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_NEAR(s.std, std::sqrt(1.25), 1e-12);
  EXPECT_NEAR(s.rmse, std::sqrt(7.5), 1e-12);
}

TEST(Stats, NinetiethPercentileIsTheNearestRank) {
  EXPECT_EQ(compute_stats({}).count, 0u);
  std::vector<double> v;
  for (int i = 10; i >= 0; --i) v.push_back(i);  // 0..10, unsorted
  const ErrorStats s = compute_stats(v);
  EXPECT_EQ(s.count, 11u);
  EXPECT_DOUBLE_EQ(s.median, 5.0);
  EXPECT_DOUBLE_EQ(s.p90, 9.0);
  EXPECT_DOUBLE_EQ(s.max, 10.0);
}

}  // namespace
}  // namespace cdc::geometry
