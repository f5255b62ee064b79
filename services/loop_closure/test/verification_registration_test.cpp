// Verification's registration (verification_registration(): GICP, judged by fitness and overlap)
// recovers known transforms, gives information in the pose graph's frames, and is the same on
// prepared clouds as on plain ones.
#include "cdc/loop_closure/loop_types.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace cdc::loops {
namespace {

using odometry::RegistrationResult;

std::vector<Eigen::Vector3d> to_double(const std::vector<Eigen::Vector3f>& pts) {
  std::vector<Eigen::Vector3d> out;
  for (const auto& p : pts) out.push_back(p.cast<double>());
  return out;
}

// Two plain clouds registered as verification registers them.
RegistrationResult register_clouds(const std::vector<Eigen::Vector3f>& source,
                                   const std::vector<Eigen::Vector3f>& target, const Eigen::Isometry3d& guess) {
  return odometry::register_clouds(to_double(source), to_double(target), guess, verification_registration());
}

std::vector<Eigen::Vector3f> scene(uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Eigen::Vector3f> pts;
  for (int i = 0; i < 6000; ++i) pts.emplace_back(30 * u(rng), 30 * u(rng), -1.8f);  // ground
  for (int w = 0; w < 6; ++w) {                                                      // walls
    const float x0 = 25 * u(rng), y0 = 25 * u(rng), a = 3.1416f * u(rng);
    for (int i = 0; i < 1500; ++i) {
      const float s = 8 * u(rng);
      pts.emplace_back(x0 + s * std::cos(a), y0 + s * std::sin(a), 4 * (u(rng) + 1) - 1.8f);
    }
  }
  for (int p = 0; p < 15; ++p) {  // poles
    const float x0 = 25 * u(rng), y0 = 25 * u(rng);
    for (int i = 0; i < 200; ++i) pts.emplace_back(x0 + 0.1f * u(rng), y0 + 0.1f * u(rng), 3 * (u(rng) + 1) - 1.8f);
  }
  return pts;
}

class RegistrationRecovers : public ::testing::TestWithParam<int> {};

TEST_P(RegistrationRecovers, AKnownTransformForwardAndInverse) {
  std::mt19937 rng(static_cast<uint32_t>(GetParam()));
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // T_target_source
  T.translation() = Eigen::Vector3d(1.5 * u(rng), 1.5 * u(rng), 0.1 * u(rng));
  T.linear() = Eigen::AngleAxisd(0.3 * u(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const auto target = scene(10 + static_cast<uint32_t>(GetParam()));
  std::vector<Eigen::Vector3f> source;
  const Eigen::Isometry3f Ts_t = T.inverse().cast<float>();
  for (const auto& p : target) source.push_back(Ts_t * p);
  for (bool inverse : {false, true}) {
    const auto& s = inverse ? target : source;
    const auto& t = inverse ? source : target;
    const Eigen::Isometry3d want = inverse ? T.inverse() : T;
    Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
    guess.linear() =
        Eigen::AngleAxisd(Eigen::AngleAxisd(want.rotation()).angle() * (want.rotation()(1, 0) >= 0 ? 1 : -1),
                          Eigen::Vector3d::UnitZ())
            .toRotationMatrix();  // yaw known (Scan Context)
    const RegistrationResult r = register_clouds(s, t, guess);
    ASSERT_TRUE(r.converged);
    EXPECT_LT((r.T_target_source.translation() - want.translation()).norm(), 0.05) << (inverse ? "inverse" : "forward");
    EXPECT_LT(Eigen::AngleAxisd(r.T_target_source.rotation().transpose() * want.rotation()).angle(), 0.005);
    EXPECT_GT(r.overlap, 0.9);
    EXPECT_LT(r.fitness, 0.05);
  }
}

INSTANTIATE_TEST_SUITE_P(SeededPerturbations, RegistrationRecovers, ::testing::Values(1, 2, 3));

TEST(Registration, InformationIsInTheGraphsResidualFrames) {
  // A corridor along the target's x (two long walls, the ground, one pole far down the corridor): the
  // translation along it is the weakest direction. The source is turned 90 deg, so in the source's
  // frame that direction is y; the information's translation block is in the target's frame.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> u(-1, 1);
  std::vector<Eigen::Vector3f> target;
  for (int i = 0; i < 4000; ++i) target.emplace_back(40 * u(rng), 3 * u(rng), -1.8f);
  for (const float y : {-3.f, 3.f}) {
    for (int i = 0; i < 4000; ++i) target.emplace_back(40 * u(rng), y, 2 * (u(rng) + 1) - 1.8f);
  }
  for (int i = 0; i < 100; ++i) target.emplace_back(30 + 0.1f * u(rng), 2 + 0.1f * u(rng), 2 * (u(rng) + 1) - 1.8f);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();  // T_target_source
  T.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(0.5, 0.2, 0);
  std::vector<Eigen::Vector3f> source;
  for (const auto& p : target) source.push_back(T.inverse().cast<float>() * p);
  Eigen::Isometry3d guess = T;
  guess.translation() += Eigen::Vector3d(0.1, -0.1, 0);
  const RegistrationResult r = register_clouds(source, target, guess);
  ASSERT_TRUE(r.converged);
  const Eigen::Matrix3d info_t = r.information.topLeftCorner<3, 3>();
  EXPECT_LT(info_t(0, 0), 0.2 * info_t(1, 1)) << "weak along the corridor (target x)\n" << info_t;
  EXPECT_LT(info_t(0, 0), 0.2 * info_t(2, 2)) << info_t;
}

// A prepared cloud registered several times, as source and as target, gives exactly what the
// plain overload gives on the same points (loop verification reuses them across a burst).
TEST(Registration, PreparedCloudsGiveTheSameResultsAsFreshOnes) {
  const odometry::RegistrationSettings params = verification_registration();
  const auto a = scene(21), b = scene(22);
  std::vector<Eigen::Vector3f> c;
  Eigen::Isometry3f shift = Eigen::Isometry3f::Identity();
  shift.translation() = Eigen::Vector3f(0.7f, -0.4f, 0.05f);
  shift.linear() = Eigen::AngleAxisf(0.08f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  for (const auto& p : a) c.push_back(shift * p);
  const odometry::PreparedCloud pa(a, params), pb(b, params), pc(c, params);
  EXPECT_EQ(pa.size(), odometry::voxel_centroids(a, params.voxel_m).size());
  const Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
  auto same = [](const RegistrationResult& x, const RegistrationResult& y) {
    EXPECT_EQ(x.converged, y.converged);
    EXPECT_TRUE(x.T_target_source.matrix() == y.T_target_source.matrix());
    EXPECT_EQ(x.fitness, y.fitness);
    EXPECT_EQ(x.overlap, y.overlap);
    EXPECT_TRUE(x.information == y.information);
  };
  for (int round = 0; round < 2; ++round) {
    same(odometry::register_gicp(pc, pa, guess, params), register_clouds(c, a, guess));
    same(odometry::register_gicp(pa, pc, guess, params), register_clouds(a, c, guess));
    same(odometry::register_gicp(pb, pa, guess, params), register_clouds(b, a, guess));
  }
  const RegistrationResult r = odometry::register_gicp(pc, pa, guess, params);
  EXPECT_TRUE(r.converged);
  EXPECT_GT(r.overlap, 0.9);
}

TEST(Registration, DifferentPlacesDoNotOverlap) {
  const RegistrationResult r = register_clouds(scene(1), scene(2), Eigen::Isometry3d::Identity());
  EXPECT_LT(r.overlap, 0.6);  // the ground matches, the structure does not
}

}  // namespace
}  // namespace cdc::loops

#include "cdc/io/cloud.hpp"
#include "cdc/io/kitti.hpp"

#include <cstdlib>
#include <filesystem>

namespace cdc::loops {
namespace {

TEST(Registration, RealKittiPairsAgreeWithGroundTruth) {
  const char* env = std::getenv("CDC_DATA_DIR");
  const std::string d = std::string(env != nullptr ? env : "../shared/data") + "/kitti/";
  if (!std::filesystem::exists(d + "scans/seq00/000094.bin")) {
    GTEST_SKIP() << "reference data absent: " << d << "scans/seq00 not found";
  }
  const auto seq = io::kitti_lidar_trajectory(d + "poses/00.txt", io::read_kitti_calib(d + "calib_Tr.txt", "Tr_00_02"));
  for (const auto& [a, b] : {std::pair<int, int>{94, 95}, std::pair<int, int>{198, 199}}) {
    char pa[32], pb[32];
    std::snprintf(pa, sizeof pa, "%06d.bin", a);
    std::snprintf(pb, sizeof pb, "%06d.bin", b);
    const Eigen::Isometry3d gt = seq[static_cast<size_t>(a)].pose.inverse() * seq[static_cast<size_t>(b)].pose;
    const RegistrationResult r = odometry::register_clouds(io::read_cloud_xyz(d + "scans/seq00/" + pb),
                                                           io::read_cloud_xyz(d + "scans/seq00/" + pa),
                                                           Eigen::Isometry3d::Identity(), verification_registration());
    const Eigen::Isometry3d e = gt.inverse() * r.T_target_source;
    const double deg = Eigen::AngleAxisd(e.rotation()).angle() * 180 / M_PI;
    std::printf("KITTI 00 %d-%d: %.4f m, %.4f deg from ground truth\n", a, b, e.translation().norm(), deg);
    EXPECT_LT(e.translation().norm(), 0.03);
    EXPECT_LT(deg, 0.2);
  }
}

}  // namespace
}  // namespace cdc::loops
