// cdc-bench-frontend: the front-end's odometry on the simulated single-robot KITTI trajectory
// (full length by default): KITTI drift, ATE and scans per second on one core, per configuration
// (VLP-16 and HDL-64E, LiDAR-inertial and LiDAR-only), and peak memory. Sweeps are simulated with
// real motion distortion from the continuous-time trajectory; the IMU at 200 Hz with consumer
// MEMS noise and bias random walk. Only FrontendCore::process is timed. Last line: one JSON object.
#include "cdc/frontend/frontend_core.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/io/kitti.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/missions.hpp"
#include "cdc/sim/trajectory.hpp"
#include "cdc/sim/world.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <malloc.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <random>
#include <string>

namespace {

using namespace cdc;

// The continuous-time drive through a 10 Hz trajectory's poses, and a city generated around it.
void drive_and_world(const geometry::Trajectory& poses, uint64_t seed, sim::SplineTrajectory& traj, sim::World& world) {
  std::vector<Eigen::Isometry3d> controls;
  std::vector<Eigen::Vector3d> path;
  for (const auto& sp : poses) {
    controls.push_back(sp.pose);
    path.push_back(sp.pose.translation());
  }
  traj = sim::SplineTrajectory(controls, static_cast<double>(poses.front().stamp_ns) * 1e-9, 0.1);
  sim::WorldOptions wo;
  wo.seed = seed;
  world = sim::World::generate({path}, wo);
}

long rss_kb(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind(field, 0) == 0) return std::stol(line.substr(std::strlen(field)));
  }
  return -1;
}

// A long drive (procedural stadium laps along rays, VLP-16 with IMU): resident memory sampled
// every simulated minute, to show that the front-end's memory stays bounded.
nlohmann::json memory_run(double minutes, const frontend::FrontendParams& params) {
  sim::MissionOptions mo;
  mo.pattern = sim::MissionPattern::kRays;
  mo.robots = 1;
  mo.speed_mps = 8;
  mo.size_m = 400;
  mo.duration_s = minutes * 60 + 2;
  sim::SplineTrajectory traj;
  sim::World world;
  drive_and_world(sim::procedural_mission(mo).front(), 2, traj, world);
  const std::vector<sim::ImuSample> imu =
      sim::simulate_imu(traj, Eigen::Isometry3d::Identity(), traj.start(), traj.end(), 200.0, sim::ImuNoise{}, 13);
  size_t imu_next = 0;
  frontend::FrontendCore core(params);
  std::mt19937_64 rng(3);
  nlohmann::json samples = nlohmann::json::array();
  const long before = rss_kb("VmRSS:");
  std::vector<frontend::ScanPoint> scan;
  size_t n = 0;
  for (double t = traj.start(); t + 0.1 < traj.end() && t < traj.start() + minutes * 60; t += 0.1, ++n) {
    scan.clear();
    for (const auto& p : sim::sweep(
             world, sim::LidarModel::vlp16(), [&](double dt) { return traj.pose(t + dt); }, rng)) {
      scan.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
    }
    while (imu_next < imu.size() && imu[imu_next].t <= t + 0.1) {
      core.add_imu({static_cast<int64_t>(imu[imu_next].t * 1e9), imu[imu_next].gyro, imu[imu_next].accel});
      ++imu_next;
    }
    core.process(static_cast<int64_t>(t * 1e9), scan);
    if (n % 600 == 599) {
      // glibc's view: bytes in use by the program against bytes the heap holds (fragmentation).
      const struct mallinfo2 mi = mallinfo2();
      samples.push_back({{"minute", (n + 1) / 600},
                         {"rss_kb", rss_kb("VmRSS:")},
                         {"map_voxels", core.map_voxels()},
                         {"heap_in_use_kb", mi.uordblks / 1024},
                         {"heap_held_kb", (mi.arena + mi.hblkhd) / 1024}});
      std::printf("minute %zu: RSS %ld kB, %zu map voxels, heap in use %zu kB of %zu kB held\n", (n + 1) / 600,
                  rss_kb("VmRSS:"), core.map_voxels(), mi.uordblks / 1024, (mi.arena + mi.hblkhd) / 1024);
      std::fflush(stdout);
    }
  }
  return {{"minutes", minutes},      {"scans", n},         {"imu_predictions", core.stats().imu_predictions},
          {"rss_before_kb", before}, {"samples", samples}, {"peak_rss_kb", rss_kb("VmHWM:")}};
}

long peak_rss_kb() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::stol(line.substr(6));
  }
  return -1;
}

struct Setup {
  sim::SplineTrajectory traj;
  sim::World world;
  std::vector<double> stamps;  // sweep starts [s]
  std::vector<sim::ImuSample> imu;
};

nlohmann::json run(const Setup& s, const sim::LidarModel& lidar, bool use_imu, const frontend::FrontendParams& params,
                   const std::string& name, const std::string& out_dir) {
  frontend::FrontendCore core(params);
  std::mt19937_64 rng(7);
  geometry::Poses est, gt;
  double busy_s = 0;
  double iterations = 0;
  size_t imu_next = 0;
  const Eigen::Isometry3d T0 = s.traj.pose(s.stamps.front());
  std::vector<frontend::ScanPoint> pts;
  for (double t : s.stamps) {
    pts.clear();
    for (const auto& p : sim::sweep(
             s.world, lidar, [&](double dt) { return s.traj.pose(t + dt); }, rng)) {
      pts.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
    }
    const auto t_start = std::chrono::steady_clock::now();
    if (use_imu) {
      while (imu_next < s.imu.size() && s.imu[imu_next].t <= t + 0.1) {
        const auto& m = s.imu[imu_next++];
        core.add_imu({static_cast<int64_t>(m.t * 1e9), m.gyro, m.accel});
      }
    }
    const frontend::ScanOut o = core.process(static_cast<int64_t>(t * 1e9), pts);
    busy_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
    iterations += o.registration.iterations;
    est.push_back(o.T_odom_raw);
    gt.push_back(T0.inverse() * s.traj.pose(t));
  }
  const geometry::KittiDrift drift = geometry::compute_kitti_drift(est, gt);
  const geometry::AteResult ate = geometry::compute_ate(est, gt, geometry::AlignMode::kSE3);
  const double rate = static_cast<double>(s.stamps.size()) / busy_s;
  const frontend::FrontendStats& st = core.stats();
  // The window's gravity against the truth (the odometry frame is the first sweep's).
  nlohmann::json gravity_error_deg;  // null without IMU
  std::string gravity_text;
  if (const auto g = core.gravity()) {
    const Eigen::Vector3d g_true = T0.rotation().transpose() * sim::kGravity;
    const double deg = std::acos(std::clamp(g->normalized().dot(g_true.normalized()), -1.0, 1.0)) * 180 / M_PI;
    gravity_error_deg = deg;
    gravity_text = ", gravity " + std::to_string(deg).substr(0, 5) + " deg off";
  }
  std::printf(
      "%-18s %zu scans: drift %.3f %% / %.4f deg/100m, ATE %.3f m, %.1f scans/s, %llu registration failures, "
      "%.1f iterations per scan (last pass); IMU window: %llu predictions, %llu rejected, %llu restarts%s\n",
      name.c_str(), s.stamps.size(), drift.translation_pct, drift.rotation_deg_per_100m, ate.translation.rmse, rate,
      static_cast<unsigned long long>(st.registration_failures), iterations / static_cast<double>(s.stamps.size()),
      static_cast<unsigned long long>(st.imu_predictions), static_cast<unsigned long long>(st.imu_predictions_rejected),
      static_cast<unsigned long long>(st.imu_window_restarts), gravity_text.c_str());
  if (!out_dir.empty()) {
    std::ofstream f(std::filesystem::path(out_dir) / (name + ".txt"));
    for (size_t i = 0; i < est.size(); ++i) {
      f << s.stamps[i] << ' ' << est[i].translation().transpose() << ' ' << gt[i].translation().transpose() << '\n';
    }
  }
  return {{"drift_trans_pct", drift.translation_pct},
          {"drift_rot_deg_per_100m", drift.rotation_deg_per_100m},
          {"ate_m", ate.translation.rmse},
          {"scans_per_s", rate},
          {"scans", s.stamps.size()},
          {"registration_failures", core.stats().registration_failures},
          {"keyframes", core.stats().keyframes},
          {"imu_predictions", st.imu_predictions},
          {"gravity_error_deg", gravity_error_deg}};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-bench-frontend: front-end odometry on the simulated single-robot KITTI trajectory"};
  const char* env = std::getenv("CDC_DATA_DIR");
  std::string data = env != nullptr ? env : "../shared/data", seq = "05", out_dir;
  size_t max_scans = 0;
  std::vector<std::string> configs = {"vlp16", "hdl64", "vlp16_lidar_only", "hdl64_lidar_only"};
  app.add_option("--data", data, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  app.add_option("--seq", seq, "KITTI sequence")->capture_default_str();
  app.add_option("--scans", max_scans, "at most this many scans (0: the whole sequence)")->capture_default_str();
  app.add_option("--configs", configs, "configurations to run")->capture_default_str();
  app.add_option("--out", out_dir, "write per-configuration trajectories here");
  bool no_deskew = false, no_imu_window = false, imu_deskew = false, no_gravity_refinement = false, no_level = false;
  double memory_minutes = 0;
  app.add_option("--memory-minutes", memory_minutes,
                 "instead: a drive this long, reporting resident memory every minute");
  app.add_flag("--no-deskew", no_deskew, "turn deskewing off (for comparison)");
  app.add_flag(
      "--no-imu-window", no_imu_window,
      "predict from constant velocity and the raw gyro instead of the sliding-window IMU estimator (for comparison)");
  app.add_flag(
      "--imu-deskew", imu_deskew,
      "deskew with the IMU's whole motion (translation from the window's velocity) instead of its rotation and "
      "constant-velocity translation (for comparison)");
  app.add_flag(
      "--no-gravity-refinement", no_gravity_refinement,
      "hold the IMU window's gravity at its first alignment instead of refining it in every window (for comparison)");
  app.add_flag("--no-level", no_level,
               "do not level the odometry with the IMU window's gravity "
               "(roll, pitch and height then follow the map's tilt; for comparison)");
  CLI11_PARSE(app, argc, argv);
  // The front-end as the comparison flags set it, for every run below.
  frontend::FrontendParams base;
  base.deskew = !no_deskew;
  base.imu_window = !no_imu_window;
  base.imu_deskew = imu_deskew;
  base.window.refine_gravity = !no_gravity_refinement;
  base.level_with_gravity = !no_level;
  if (memory_minutes > 0) {
    nlohmann::json j{{"memory", memory_run(memory_minutes, base)}};
    std::cout << j.dump() << '\n';
    return 0;
  }
  const std::string poses = data + "/kitti/poses/" + seq + ".txt";
  if (!std::filesystem::exists(poses)) {
    std::cerr << "cdc-bench-frontend: " << poses << " not found (set --data or CDC_DATA_DIR)\n";
    return 2;
  }
  const auto full = io::kitti_lidar_trajectory(poses, io::read_kitti_calib(data + "/kitti/calib_Tr.txt", "Tr_04_10"));
  Setup s;
  drive_and_world(full, 5, s.traj, s.world);
  for (double t = s.traj.start(); t + 0.1 < s.traj.end(); t += 0.1) {
    s.stamps.push_back(t);
    if (max_scans > 0 && s.stamps.size() >= max_scans) break;
  }
  s.imu = sim::simulate_imu(s.traj, Eigen::Isometry3d::Identity(), s.stamps.front() - 0.5, s.stamps.back() + 0.2, 200.0,
                            sim::ImuNoise{}, 11);
  if (!out_dir.empty()) std::filesystem::create_directories(out_dir);
  nlohmann::json out;
  for (const std::string& c : configs) {
    const bool hdl = c.rfind("hdl64", 0) == 0;
    const bool imu = c.find("lidar_only") == std::string::npos;
    frontend::FrontendParams p = base;
    if (hdl) p.image_columns = 2000;
    out[c] = run(s, hdl ? sim::LidarModel::hdl64() : sim::LidarModel::vlp16(), imu, p, c, out_dir);
  }
  out["sequence"] = seq;
  out["peak_rss_kb"] = peak_rss_kb();
  std::cout << out.dump() << '\n';
  return 0;
}
