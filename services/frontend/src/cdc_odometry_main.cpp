// cdc-odometry: the front-end core over a recorded dataset, without DDS: one robot of a cdc-sim
// dataset folder (scans with per-point times and rings, IMU, calibration, ground truth) or a KITTI
// velodyne folder (*.bin, 10 Hz, optional ground-truth poses). Writes the odometry (TUM and KITTI
// formats) and the keyframes, and reports drift and ATE when there is ground truth.
#include "cdc/frontend/frontend_core.hpp"
#include "frontend_config.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/sim/kitti.hpp"
#include "dataset_reader.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <iostream>

namespace fs = std::filesystem;
using namespace cdc;

namespace {

struct Input {
  std::vector<sim::DatasetScan> scans;
  std::vector<sim::DatasetImu> imu;
  geometry::Trajectory groundtruth;
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();
};

Input read_sim(const std::string& dir, uint32_t robot, size_t max_scans) {
  Input in;
  std::map<uint32_t, geometry::Trajectory> gt;
  for (auto& s : sim::list_dataset_scans(dir, max_scans, &gt)) {
    if (s.robot == robot) in.scans.push_back(std::move(s));
  }
  if (in.scans.empty()) throw std::runtime_error(dir + ": no scans of robot " + std::to_string(robot));
  const fs::path rd = fs::path(dir) / ("robot_" + std::to_string(robot));
  in.imu = sim::read_dataset_imu(rd / "imu.csv");
  in.groundtruth = gt[robot];
  const YAML::Node calib = YAML::LoadFile((rd / "calib.yaml").string());
  const auto t = calib["T_lidar_imu"]["position"].as<std::vector<double>>();
  const auto q = calib["T_lidar_imu"]["orientation"].as<std::vector<double>>();
  if (t.size() != 3 || q.size() != 4) throw std::runtime_error((rd / "calib.yaml").string() + ": T_lidar_imu needs 3 + 4 numbers");
  in.T_lidar_imu = geometry::make_pose(Eigen::Vector3d(t[0], t[1], t[2]), Eigen::Quaterniond(q[3], q[0], q[1], q[2]).normalized());
  return in;
}

Input read_kitti(const std::string& dir, const std::string& poses, const std::string& calib, size_t max_scans) {
  Input in;
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".bin") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  if (files.empty()) throw std::runtime_error(dir + ": no .bin scans");
  geometry::Trajectory gt;
  if (!poses.empty()) gt = sim::kitti_lidar_trajectory(poses, sim::read_kitti_calib(calib, "Tr_00_02"));
  for (size_t i = 0; i < files.size() && (max_scans == 0 || i < max_scans); ++i) {
    const size_t index = static_cast<size_t>(std::stoul(files[i].stem().string()));
    sim::DatasetScan s{static_cast<int64_t>(index) * 100'000'000, 0, index, files[i], {}, std::nullopt};
    if (index < gt.size()) {
      s.truth = gt[index].pose;
      in.groundtruth.push_back({s.stamp_ns, gt[index].pose});
    }
    in.scans.push_back(std::move(s));
  }
  return in;
}

void write_kitti_lines(const fs::path& p, const geometry::Trajectory& t) { geometry::write_kitti(p.string(), t); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-odometry: runs the front-end core over a recorded dataset without DDS and writes its trajectory.\n"
      "  cdc-odometry DATASET [--robot K]               a cdc-sim dataset folder (robot_K/...)\n"
      "  cdc-odometry VELODYNE_DIR --kitti [--poses P]  a KITTI velodyne folder (no IMU, no per-point times)"};
  std::string input, out_dir, poses, calib, config_path;
  uint32_t robot = 0;
  size_t max_scans = 0;
  bool kitti = false, lidar_only = false, no_deskew = false, no_imu_window = false, imu_deskew = false, json = false;
  bool no_level = false;
  app.add_option("dataset", input, "dataset folder")->required()->check(CLI::ExistingDirectory);
  app.add_option("--robot", robot, "robot of a cdc-sim dataset")->capture_default_str();
  app.add_flag("--kitti", kitti, "DATASET is a KITTI velodyne folder");
  app.add_option("--poses", poses, "KITTI ground-truth poses (for --kitti)")->check(CLI::ExistingFile);
  app.add_option("--calib", calib, "KITTI calib_Tr.txt (for --kitti --poses)")->check(CLI::ExistingFile);
  app.add_option("--config", config_path,
                 "front-end configuration (services/frontend/config/frontend.yaml; default: its defaults); the flags "
                 "below override it")
      ->check(CLI::ExistingFile);
  app.add_flag("--lidar-only", lidar_only, "ignore the IMU");
  app.add_flag("--no-deskew", no_deskew, "do not deskew sweeps");
  app.add_flag("--no-imu-window", no_imu_window,
               "predict sweeps from constant velocity and the raw gyro instead of the sliding-window IMU estimator");
  app.add_flag("--imu-deskew", imu_deskew,
               "deskew with the IMU's whole motion (translation from the window's velocity) instead of its rotation and "
               "constant-velocity translation");
  app.add_flag("--no-level", no_level,
               "do not level the odometry with the IMU window's gravity "
               "(roll, pitch and height then follow the map's tilt)");
  app.add_option("--max-scans", max_scans, "at most this many scans (0: all)")->capture_default_str();
  app.add_option("--out", out_dir, "write odometry.tum, odometry.kitti, keyframes.tum and report.json here");
  app.add_flag("--json", json, "print the report as one JSON object");
  CLI11_PARSE(app, argc, argv);
  try {
    if (kitti && !poses.empty() && calib.empty()) throw std::runtime_error("--poses needs --calib (calib_Tr.txt)");
    const Input in = kitti ? read_kitti(input, poses, calib, max_scans) : read_sim(input, robot, max_scans);
    const frontend::FrontendNodeOptions options = frontend::load_frontend_options(config_path);
    frontend::FrontendParams params = options.core;
    if (no_deskew) params.deskew = false;
    if (no_imu_window) params.imu_window = false;
    if (imu_deskew) params.imu_deskew = true;
    if (no_level) params.level_with_gravity = false;
    params.T_lidar_imu = in.T_lidar_imu;
    frontend::FrontendCore core(params);
    const bool use_imu = !lidar_only && options.use_imu && !in.imu.empty();
    size_t imu_next = 0;
    geometry::Trajectory odometry, keyframes;
    std::vector<frontend::ScanPoint> pts;
    double busy = 0;
    for (const sim::DatasetScan& s : in.scans) {
      pts.clear();
      for (const sim::DatasetPoint& p : sim::read_dataset_scan(s.bin, s.meta)) {
        pts.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
      }
      const auto t0 = std::chrono::steady_clock::now();
      while (use_imu && imu_next < in.imu.size() && in.imu[imu_next].stamp_ns <= s.stamp_ns + 100'000'000) {
        core.add_imu({in.imu[imu_next].stamp_ns, in.imu[imu_next].gyro, in.imu[imu_next].accel});
        ++imu_next;
      }
      const frontend::ScanOut o = core.process(s.stamp_ns, pts);
      busy += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      odometry.push_back({s.stamp_ns, o.T_odom_raw});
      if (o.keyframe) keyframes.push_back({o.keyframe->stamp_ns, o.keyframe->T_odom_keyframe});
    }
    nlohmann::json report{{"dataset", input},
                          {"scans", odometry.size()},
                          {"keyframes", keyframes.size()},
                          {"imu", use_imu},
                          {"scans_per_s", static_cast<double>(odometry.size()) / std::max(busy, 1e-9)},
                          {"registration_failures", core.stats().registration_failures},
                          {"registration_rejected", core.stats().registration_rejected},
                          {"imu_predictions", core.stats().imu_predictions},
                          {"imu_window_restarts", core.stats().imu_window_restarts},
                          {"max_level_deg", core.stats().max_level_deg}};
    // Ground truth, expressed from the first scan's pose like the odometry.
    const auto gt_index = [&](int64_t stamp) { return geometry::interpolate_at(in.groundtruth, stamp); };
    geometry::Poses est, gt;
    const auto first = in.groundtruth.empty() ? std::nullopt : gt_index(odometry.front().stamp_ns);
    for (const auto& sp : odometry) {
      const auto g = first ? gt_index(sp.stamp_ns) : std::nullopt;
      if (!g) continue;
      est.push_back(sp.pose);
      gt.push_back(first->inverse() * *g);
    }
    if (est.size() > 20) {
      const geometry::KittiDrift d = geometry::compute_kitti_drift(est, gt);
      const geometry::AteResult ate = geometry::compute_ate(est, gt, geometry::AlignMode::kSE3);
      report["drift_trans_pct"] = d.translation_pct;
      report["drift_rot_deg_per_100m"] = d.rotation_deg_per_100m;
      report["ate_m"] = ate.translation.rmse;
    }
    if (!out_dir.empty()) {
      fs::create_directories(out_dir);
      geometry::write_tum((fs::path(out_dir) / "odometry.tum").string(), odometry);
      write_kitti_lines(fs::path(out_dir) / "odometry.kitti", odometry);
      geometry::write_tum((fs::path(out_dir) / "keyframes.tum").string(), keyframes);
      std::ofstream(fs::path(out_dir) / "report.json") << report.dump(2) << '\n';
    }
    if (json) {
      std::cout << report.dump() << '\n';
    } else {
      std::cout << input << ": " << odometry.size() << " scans, " << keyframes.size() << " keyframes, "
                << report["scans_per_s"].get<double>() << " scans/s";
      if (report.contains("ate_m")) {
        std::cout << "; drift " << report["drift_trans_pct"].get<double>() << " % / " << report["drift_rot_deg_per_100m"].get<double>()
                  << " deg/100m, ATE " << report["ate_m"].get<double>() << " m";
      }
      std::cout << '\n';
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "cdc-odometry: " << e.what() << '\n';
    return 1;
  }
}
