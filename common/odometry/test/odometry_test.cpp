// Scan-to-map registration and GICP on simulated clouds: a known transform is recovered from seeded
// perturbations, forward and inverse; the voxel map stays bounded as the robot moves on. IMU
// preintegration predicts a simulated drive, and its bias Jacobians agree with integrating again.
#include "cdc/geometry/se3.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/kitti.hpp"
#include "cdc/io/transform_file.hpp"
#include "cdc/odometry/imu_preintegration.hpp"
#include "cdc/odometry/normals.hpp"
#include "cdc/odometry/registration.hpp"
#include "cdc/odometry/voxel_map.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/trajectory.hpp"
#include "cdc/sim/world.hpp"
#include "sim_scene.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

namespace cdc::odometry {
namespace {

// 200 m of path and a VLP-16.
struct Scene : test::SimScene {
  Scene()
      : test::SimScene(test::SceneOptions{.path_points = 100,
                                          .step_m = 2.0,
                                          .slant_m = 0.3,
                                          .world_seed = 8,
                                          .spacing_m = 8,
                                          .lidar = sim::LidarModel::vlp16()}) {}
};

Eigen::Isometry3d pose(double x, double y, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 1.73 + 0.003 * x);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

TEST(Registration, RecoversAKnownTransformFromSeededPerturbations) {
  Scene s;
  // A local map of a single scan (the hardest case: its ground is rings).
  const Eigen::Isometry3d A = pose(0, 0, 0.05);
  VoxelMap map;
  for (const Eigen::Isometry3d& T : {A}) {
    std::vector<Eigen::Vector3d> world;
    for (const auto& p : voxel_filter(s.scan(T), 0.5)) world.push_back(T * p);
    map.add(world);
  }
  std::mt19937 rng(21);
  std::normal_distribution<double> nt(0, 0.3), nr(0, 0.03);
  for (const bool inverse : {false, true}) {
    const Eigen::Isometry3d B = inverse ? pose(-1.5, 0.4, 0.05 - 0.08) : pose(1.5, -0.4, 0.05 + 0.08);
    std::vector<uint16_t> rings;
    const std::vector<Eigen::Vector3d> full = s.scan(B, &rings);
    const std::vector<Eigen::Vector3d> all_normals = range_image_normals(full, rings);
    std::vector<Eigen::Vector3d> b, normals;
    for (size_t i : voxel_filter_indices(full, 1.0)) {
      if (all_normals[i].squaredNorm() > 0.5) {
        b.push_back(full[i]);
        normals.push_back(all_normals[i]);
      }
    }
    for (int trial = 0; trial < 5; ++trial) {
      geometry::Vector6d d;
      d << nt(rng), nt(rng), 0.3 * nt(rng), 0.3 * nr(rng), 0.3 * nr(rng), nr(rng);
      const Eigen::Isometry3d guess = B * geometry::se3_exp(d);
      const RegistrationResult r = register_to_map(b, normals, map, guess, RegistrationSettings{});
      ASSERT_TRUE(r.converged);
      const Eigen::Isometry3d e = B.inverse() * r.T_target_source;
      EXPECT_LT(e.translation().norm(), 0.03) << "trial " << trial << (inverse ? " inverse" : "");
      EXPECT_LT(geometry::rotation_angle(e.rotation()), 0.2 * M_PI / 180) << "trial " << trial;
      EXPECT_GT(r.correspondences, 300);
    }
  }
}

TEST(Registration, GicpRecoversAKnownTransformFromSeededPerturbations) {
  Scene s;
  const Eigen::Isometry3d A = pose(0, 0, 0.05);
  std::vector<Eigen::Vector3d> target;
  for (const auto& p : s.scan(A)) target.push_back(A * p);  // the target in the world frame
  std::mt19937 rng(22);
  std::normal_distribution<double> nt(0, 0.3), nr(0, 0.03);
  for (const bool inverse : {false, true}) {
    const Eigen::Isometry3d B = inverse ? pose(-1.5, 0.4, 0.05 - 0.08) : pose(1.5, -0.4, 0.05 + 0.08);
    const std::vector<Eigen::Vector3d> source = s.scan(B);
    for (int trial = 0; trial < 3; ++trial) {
      geometry::Vector6d d;
      d << nt(rng), nt(rng), 0.3 * nt(rng), 0.3 * nr(rng), 0.3 * nr(rng), nr(rng);
      RegistrationSettings p = RegistrationSettings::gicp();
      // A VLP-16 sweep is sparse: at the 0.1 m default, a point's neighbours lie on its own ring (a
      // line, not a plane) and pull the estimate towards zero motion (0.24 m short here). Voxels
      // coarser than the ring spacing give planes again.
      p.voxel_m = 0.5;
      p.neighbours = 20;
      const RegistrationResult r = register_clouds(source, target, B * geometry::se3_exp(d), p);
      ASSERT_TRUE(r.converged);
      EXPECT_LT(r.iterations, p.max_iterations) << "converged within the eps, not at the limit";
      const Eigen::Isometry3d e = B.inverse() * r.T_target_source;
      EXPECT_LT(e.translation().norm(), 0.03) << "trial " << trial << (inverse ? " inverse" : "");
      EXPECT_LT(geometry::rotation_angle(e.rotation()), 0.2 * M_PI / 180) << "trial " << trial;
    }
  }
}

TEST(VoxelMap, StaysBoundedAsTheRobotMovesOn) {
  VoxelMapParams p;
  p.max_range_m = 50;
  VoxelMap map(p);
  size_t most = 0;
  for (int step = 0; step < 400; ++step) {
    const Eigen::Vector3d c(5.0 * step, 0, 0);
    std::vector<Eigen::Vector3d> pts;
    for (int i = -40; i <= 40; ++i) {
      for (int j = -10; j <= 10; ++j) pts.emplace_back(c.x() + i, c.y() + j, 0.0);
    }
    map.add(pts);
    map.remove_far(c);
    most = std::max(most, map.voxels());
  }
  // A 100 x 21 m strip of ground at most, whatever the distance travelled (2 km).
  EXPECT_LE(most, 101u * 21u * 2u);
  EXPECT_LE(map.points(), map.voxels() * 20u);
  EXPECT_GT(map.voxels(), 1000u);
  // Voxels far behind are gone; the surface under the robot is found.
  Eigen::Vector3d q;
  double d2 = 0;
  EXPECT_FALSE(map.nearest(Eigen::Vector3d(0, 0, 0), q, d2));
  ASSERT_TRUE(map.nearest(Eigen::Vector3d(5.0 * 399 + 0.2, 0.3, 0.1), q, d2));
  EXPECT_NEAR(std::sqrt(d2), std::sqrt(0.2 * 0.2 + 0.3 * 0.3 + 0.1 * 0.1), 1e-9);
}

}  // namespace
}  // namespace cdc::odometry

namespace cdc::odometry {
namespace {

std::string data_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr ? env : "../shared/data";
}

// Source registered onto the target from the identity, by either method.
Eigen::Isometry3d align(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                        RegistrationMethod method = RegistrationMethod::kPointToPlane) {
  const RegistrationSettings p =
      method == RegistrationMethod::kGicp ? RegistrationSettings::gicp() : RegistrationSettings{};
  const RegistrationResult r = register_clouds(source, target, Eigen::Isometry3d::Identity(), p);
  EXPECT_TRUE(r.converged);
  if (method == RegistrationMethod::kGicp) {
    EXPECT_LT(r.iterations, p.max_iterations) << "converged within the eps";
  }
  return r.T_target_source;
}

TEST(Registration, RealKittiPairsAgreeWithGroundTruth) {
  const std::string d = data_dir();
  if (!std::filesystem::exists(d + "/kitti/scans/seq00/000094.bin")) {
    GTEST_SKIP() << "reference data absent: " << d << "/kitti/scans/seq00 not found";
  }
  struct Pair {
    std::string name;
    std::vector<Eigen::Vector3d> source, target;
    Eigen::Isometry3d T_target_source;
  };
  std::vector<Pair> pairs;
  const auto seq = io::kitti_lidar_trajectory(d + "/kitti/poses/00.txt",
                                              io::read_kitti_calib(d + "/kitti/calib_Tr.txt", "Tr_00_02"));
  for (const auto& [a, b] : {std::pair<int, int>{94, 95}, std::pair<int, int>{198, 199}}) {
    char pa[64], pb[64];
    std::snprintf(pa, sizeof pa, "/kitti/scans/seq00/%06d.bin", a);
    std::snprintf(pb, sizeof pb, "/kitti/scans/seq00/%06d.bin", b);
    pairs.push_back({"KITTI 00 " + std::to_string(a) + "-" + std::to_string(b), io::read_cloud_xyz(d + pb),
                     io::read_cloud_xyz(d + pa),
                     seq[static_cast<size_t>(a)].pose.inverse() * seq[static_cast<size_t>(b)].pose});
  }
  for (const Pair& p : pairs) {
    ASSERT_GT(p.source.size(), 10000u) << p.name;
    for (const RegistrationMethod m : {RegistrationMethod::kPointToPlane, RegistrationMethod::kGicp}) {
      const std::string name = p.name + (m == RegistrationMethod::kGicp ? " (GICP)" : " (point-to-plane)");
      const Eigen::Isometry3d e = p.T_target_source.inverse() * align(p.source, p.target, m);
      const double deg = geometry::rotation_angle(e.rotation()) * 180 / M_PI;
      std::printf("%s: %.4f m, %.4f deg from the reference\n", name.c_str(), e.translation().norm(), deg);
      EXPECT_LT(e.translation().norm(), 0.03) << name;
      EXPECT_LT(deg, 0.2) << name;
    }
  }
}

// ../shared/data/registration holds one real sweep pair (an outdoor campus, 64 beams) with two
// reference transforms, each another GICP implementation's result: small_gicp's and fast_gicp's.
// They are 1.9 cm and 0.228 deg apart, so no estimate is within 0.2 deg of both unless it falls
// between them. Ours reproduces small_gicp's (its settings: 0.1 m voxels, 10 neighbours); against
// fast_gicp's, the translation is asserted and the rotation only printed: fast_gicp's own test holds
// its registrations to 5 cm and 1 deg of that reference, so it is no tighter than that.
TEST(Registration, AlignmentScoresRankTheTrueTransformFirst) {
  Scene s;
  const Eigen::Isometry3d A = pose(0, 0, 0.05), B = pose(1.5, -0.4, 0.13);
  std::vector<Eigen::Vector3d> target;
  for (const auto& p : s.scan(A)) target.push_back(A * p);
  const std::vector<Eigen::Vector3d> source = s.scan(B);
  const AlignmentScore truth = score_alignment(source, target, B);
  ASSERT_GT(truth.matched, truth.source_points / 5);  // a sparse VLP-16 sweep: many points have no neighbour on a plane
  EXPECT_GE(truth.within_2cm, truth.within_1cm);
  EXPECT_GE(truth.matched, truth.within_2cm);
  for (const auto& [dt, dyaw] : std::vector<std::pair<double, double>>{{0.03, 0}, {0, 0.3 * M_PI / 180}}) {
    const AlignmentScore off = score_alignment(source, target, B * pose(dt, 0, dyaw) * pose(0, 0, 0).inverse());
    std::printf("true: %zu within 1 cm, rms %.1f mm; %.2f m / %.2f deg off: %zu, rms %.1f mm\n", truth.within_1cm,
                truth.rms_point_to_plane_m * 1e3, dt, dyaw * 180 / M_PI, off.within_1cm,
                off.rms_point_to_plane_m * 1e3);
    EXPECT_GT(truth.within_1cm, off.within_1cm);
    EXPECT_LT(truth.rms_point_to_plane_m, off.rms_point_to_plane_m);
  }
  EXPECT_EQ(score_alignment(source, {}, B).matched, 0u) << "nothing to match";
}

TEST(Registration, RealSweepPairAgreesWithTheGicpReferences) {
  const std::string d = data_dir() + "/registration";
  if (!std::filesystem::exists(d + "/small_gicp/source.ply") ||
      !std::filesystem::exists(d + "/fast_gicp/relative.txt")) {
    GTEST_SKIP() << "reference data absent: " << d << " (small_gicp/, fast_gicp/) not found";
  }
  const auto source = io::read_cloud_xyz(d + "/small_gicp/source.ply"),
             target = io::read_cloud_xyz(d + "/small_gicp/target.ply");
  const Eigen::Isometry3d ref_small = io::read_transform_file(d + "/small_gicp/T_target_source.txt");
  const Eigen::Isometry3d ref_fast = io::read_transform_file(d + "/fast_gicp/relative.txt");
  // fast_gicp's copy of the pair is the same two sweeps (PCD): its clouds register to the same answer.
  const auto fast_source = io::read_cloud_xyz(d + "/fast_gicp/251371071.pcd"),
             fast_target = io::read_cloud_xyz(d + "/fast_gicp/251370668.pcd");
  ASSERT_EQ(fast_source.size(), source.size());
  const Eigen::Isometry3d T = align(source, target, RegistrationMethod::kGicp);
  const Eigen::Isometry3d T_fast_copy = align(fast_source, fast_target, RegistrationMethod::kGicp);
  auto report = [](const char* what, const Eigen::Isometry3d& e) {
    const double deg = geometry::rotation_angle(e.rotation()) * 180 / M_PI;
    std::printf("%s: %.4f m, %.4f deg\n", what, e.translation().norm(), deg);
    return std::pair<double, double>{e.translation().norm(), deg};
  };
  const auto [t_small, r_small] = report("GICP from small_gicp's reference", ref_small.inverse() * T);
  const double t_fast = report("GICP from fast_gicp's reference", ref_fast.inverse() * T).first;
  report("small_gicp's reference from fast_gicp's", ref_fast.inverse() * ref_small);
  const auto [t_copy, r_copy] = report("GICP on the PCD copy from GICP on the PLY copy", T.inverse() * T_fast_copy);
  EXPECT_LT(t_small, 0.03);
  EXPECT_LT(r_small, 0.2);
  EXPECT_LT(t_fast, 0.03);
  EXPECT_LT(t_copy, 1e-3);
  EXPECT_LT(r_copy, 0.01);
}

}  // namespace
}  // namespace cdc::odometry

namespace cdc::odometry {
namespace {

// A winding, climbing drive for the IMU (spline through 0.1 s controls).
sim::SplineTrajectory imu_drive() {
  std::vector<Eigen::Isometry3d> controls;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  for (int i = 0; i < 80; ++i) {
    controls.push_back(T);
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.translation() = Eigen::Vector3d(0.8 + 0.3 * std::sin(0.05 * i), 0, 0.01 * std::sin(0.1 * i));
    step.linear() = (Eigen::AngleAxisd(0.03 * std::sin(0.07 * i), Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(0.01 * std::cos(0.09 * i), Eigen::Vector3d::UnitY()))
                        .toRotationMatrix();
    T = T * step;
  }
  return sim::SplineTrajectory(controls, 0.0, 0.1);
}

ImuPreintegration integrate(const std::vector<sim::ImuSample>& imu, const Eigen::Vector3d& bg,
                            const Eigen::Vector3d& ba) {
  ImuPreintegration pre(bg, ba);
  for (size_t i = 0; i + 1 < imu.size(); ++i) pre.integrate(imu[i].gyro, imu[i].accel, imu[i + 1].t - imu[i].t);
  return pre;
}

TEST(ImuPreintegration, PredictsADriveFromItsSamples) {
  const sim::SplineTrajectory traj = imu_drive();
  // 2 s at 200 Hz, exact samples carrying known biases, integrated with those biases.
  const Eigen::Vector3d bg(0.004, -0.003, 0.005), ba(0.05, -0.04, 0.03);
  auto imu = sim::simulate_imu(traj, Eigen::Isometry3d::Identity(), 1.0, 3.0, 200.0, sim::ImuNoise::none(), 1);
  for (auto& m : imu) {
    m.gyro += bg;
    m.accel += ba;
  }
  const ImuPreintegration pre = integrate(imu, bg, ba);
  const double t0 = imu.front().t, t1 = imu.back().t;
  EXPECT_NEAR(pre.dt(), t1 - t0, 1e-9);
  Eigen::Matrix3d R;
  Eigen::Vector3d v, p;
  pre.predict(traj.pose(t0).rotation(), traj.velocity(t0), traj.pose(t0).translation(), sim::kGravity, R, v, p);
  // Sample-and-hold over 5 ms steps: centimetres over 2 s and 20 m, against metres for a wrong bias.
  EXPECT_LT((p - traj.pose(t1).translation()).norm(), 0.03);
  EXPECT_LT((v - traj.velocity(t1)).norm(), 0.03);
  EXPECT_LT(geometry::rotation_angle(R.transpose() * traj.pose(t1).rotation()), 2e-3);
  const ImuPreintegration unbiased = integrate(imu, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  unbiased.predict(traj.pose(t0).rotation(), traj.velocity(t0), traj.pose(t0).translation(), sim::kGravity, R, v, p);
  EXPECT_GT((p - traj.pose(t1).translation()).norm(), 0.1);
  // The covariance grows with time and is symmetric positive definite.
  const Eigen::LLT<ImuPreintegration::Matrix9d> llt(pre.covariance());
  EXPECT_EQ(llt.info(), Eigen::Success);
  EXPECT_LT((pre.covariance() - pre.covariance().transpose()).norm(), 1e-15);
}

TEST(ImuPreintegration, BiasJacobiansAgreeWithIntegratingAgain) {
  const sim::SplineTrajectory traj = imu_drive();
  const auto imu = sim::simulate_imu(traj, Eigen::Isometry3d::Identity(), 1.0, 1.5, 200.0, sim::ImuNoise{}, 3);
  const ImuPreintegration at_zero = integrate(imu, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  // The first-order correction's error against integrating again with the changed biases, and the
  // change's own effect on the increments.
  struct Errors {
    double rotation, velocity, position, effect_rotation, effect_velocity;
  };
  auto errors = [&](double scale) {
    const Eigen::Vector3d dbg = scale * Eigen::Vector3d(2e-3, -1e-3, 1.5e-3),
                          dba = scale * Eigen::Vector3d(0.03, 0.02, -0.04);
    const ImuPreintegration again = integrate(imu, dbg, dba);
    return Errors{geometry::rotation_angle(at_zero.delta_R(dbg).transpose() * again.delta_R(dbg)),
                  (at_zero.delta_v(dbg, dba) - again.delta_v(dbg, dba)).norm(),
                  (at_zero.delta_p(dbg, dba) - again.delta_p(dbg, dba)).norm(),
                  geometry::rotation_angle(at_zero.delta_R(zero).transpose() * again.delta_R(dbg)),
                  (at_zero.delta_v(zero, zero) - again.delta_v(dbg, dba)).norm()};
  };
  const Errors full = errors(1.0), half = errors(0.5);
  std::printf("first-order errors: %.2e rad, %.2e m/s, %.2e m (change: %.2e rad, %.2e m/s)\n", full.rotation,
              full.velocity, full.position, full.effect_rotation, full.effect_velocity);
  EXPECT_LT(full.rotation, 1e-3 * full.effect_rotation);  // at rounding level: the rotation's correction is exact here
  EXPECT_LT(full.velocity, 1e-2 * full.effect_velocity);
  EXPECT_LT(full.position, 1e-2 * full.effect_velocity);
  // Second order: half the bias change, a quarter of the error (a wrong Jacobian leaves first-order
  // terms, which only halve).
  EXPECT_LT(half.velocity, 0.3 * full.velocity);
  EXPECT_LT(half.position, 0.3 * full.position);
}

}  // namespace
}  // namespace cdc::odometry
