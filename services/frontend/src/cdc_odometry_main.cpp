// cdc-odometry: the front-end core over a recorded dataset, without DDS: one robot of a cdc-sim
// dataset folder (scans with per-point times and rings, IMU, calibration, ground truth) or a KITTI
// velodyne folder (*.bin, 10 Hz, optional ground-truth poses). Writes the odometry (TUM and KITTI
// formats) and the keyframes, and reports drift and ATE when there is ground truth.
#include "cdc/config/cli_range.hpp"
#include "frontend_config.hpp"

#include "cdc/base/tool.hpp"
#include "cdc/frontend/frontend_core.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/io/dataset.hpp"
#include "cdc/io/kitti.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <vector>

namespace fs = std::filesystem;
using namespace cdc;

namespace {

struct Input {
  std::vector<io::DatasetScan> scans;
  std::vector<io::DatasetImu> imu;
  geometry::Trajectory groundtruth;
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();
  io::PointTimes point_times = io::PointTimes::kSensor;
  double sweep_period_s = 0.1;
};

Input read_dataset(const std::string& dir, uint32_t robot, size_t max_scans) {
  Input in;
  const io::DatasetInfo info = io::read_dataset_info(dir);
  in.point_times = info.point_times;
  in.sweep_period_s = info.sweep_period_s;
  std::map<uint32_t, geometry::Trajectory> gt;
  for (auto& s : io::list_dataset_scans(dir, max_scans, &gt)) {
    if (s.robot == robot) in.scans.push_back(std::move(s));
  }
  if (in.scans.empty()) throw std::runtime_error(dir + ": no scans of robot " + std::to_string(robot));
  const fs::path rd = fs::path(dir) / ("robot_" + std::to_string(robot));
  in.imu = io::read_dataset_imu(rd / "imu.csv");
  in.groundtruth = gt[robot];
  in.T_lidar_imu = io::read_dataset_calib(rd / "calib.yaml");
  return in;
}

// A KITTI folder as it is: no IMU, and the sweeps taken as motion-compensated (no per-point times).
Input read_kitti(const std::string& dir, const io::KittiSequenceOptions& options, size_t max_scans) {
  Input in;
  const io::KittiSequence seq = io::read_kitti_sequence(dir, options);
  in.point_times = io::PointTimes::kNone;
  in.sweep_period_s = static_cast<double>(options.period_ns) * 1e-9;
  for (size_t i = 0; i < seq.sweeps.size() && (max_scans == 0 || i < max_scans); ++i) {
    io::DatasetScan s{seq.stamps_ns[i], 0, i, seq.sweeps[i], {}, std::nullopt};
    if (!seq.poses.empty()) {
      s.truth = seq.poses[i].pose;
      in.groundtruth.push_back(seq.poses[i]);
    }
    in.scans.push_back(std::move(s));
  }
  return in;
}

// The command line.
struct Options {
  std::string input, out_dir, poses, calib, config_path, times_path, poses_frame = "camera", calib_key = "Tr_00_02";
  double period_s = 0.1;
  uint32_t robot = 0;
  size_t max_scans = 0;
  bool kitti = false, lidar_only = false, no_deskew = false, no_imu_window = false, imu_deskew = false, json = false;
  bool no_level = false;
};

void add_options(CLI::App& app, Options& o) {
  app.add_option("dataset", o.input, "dataset folder")->required()->check(CLI::ExistingDirectory);
  cdc::config::add_number_option(app, "--robot", o.robot, "robot of a cdc-sim dataset", 0, 254);
  app.add_flag("--kitti", o.kitti, "DATASET is a KITTI velodyne folder");
  app.add_option("--poses", o.poses, "poses, 3x4 row-major per sweep (for --kitti)")->check(CLI::ExistingFile);
  app.add_option("--poses-frame", o.poses_frame,
                 "camera: KITTI ground truth (T_world_cam0, needs --calib); lidar: the LiDAR's poses")
      ->check(CLI::IsMember({"camera", "lidar"}))
      ->capture_default_str();
  app.add_option("--calib", o.calib,
                 "KITTI calibration holding Tr (calib.txt or calib_Tr.txt; for --poses-frame camera)")
      ->check(CLI::ExistingFile);
  app.add_option("--calib-key", o.calib_key, "the calibration entry holding T_cam0_velo")->capture_default_str();
  app.add_option("--times", o.times_path,
                 "sweep times, seconds per line (for --kitti; default DIR/times.txt or frame x period)")
      ->check(CLI::ExistingFile);
  cdc::config::add_number_option(app, "--period", o.period_s, "sweep period [s] (for --kitti)", 0.001, 10);
  app.add_option("--config", o.config_path,
                 "front-end configuration (services/frontend/config/frontend.yaml; default: its defaults); the flags "
                 "below override it")
      ->check(CLI::ExistingFile);
  app.add_flag("--lidar-only", o.lidar_only, "ignore the IMU");
  app.add_flag("--no-deskew", o.no_deskew, "do not deskew sweeps");
  app.add_flag("--no-imu-window", o.no_imu_window,
               "predict sweeps from constant velocity and the raw gyro instead of the sliding-window IMU estimator");
  app.add_flag(
      "--imu-deskew", o.imu_deskew,
      "deskew with the IMU's whole motion (translation from the window's velocity) instead of its rotation and "
      "constant-velocity translation");
  app.add_flag("--no-level", o.no_level,
               "do not level the odometry with the IMU window's gravity "
               "(roll, pitch and height then follow the map's tilt)");
  cdc::config::add_number_option(app, "--max-scans", o.max_scans, "at most this many scans (0: all)", 0, 1e6);
  app.add_option("--out", o.out_dir, "write odometry.tum, odometry.kitti, keyframes.tum and report.json here");
  app.add_flag("--json", o.json, "print the report as one JSON object");
}

Input read_input(const Options& o) {
  if (!o.kitti) return read_dataset(o.input, o.robot, o.max_scans);
  io::KittiSequenceOptions ko;
  ko.poses = o.poses;
  ko.poses_frame = o.poses_frame == "lidar" ? io::KittiPosesFrame::kLidar : io::KittiPosesFrame::kCamera;
  ko.calib = o.calib;
  ko.calib_key = o.calib_key;
  ko.times = o.times_path;
  ko.period_ns = static_cast<int64_t>(std::llround(o.period_s * 1e9));
  return read_kitti(o.input, ko, o.max_scans);
}

// The configuration's core parameters with the flags and the input's calibration applied.
frontend::FrontendParams core_params(const frontend::FrontendNodeOptions& config, const Options& o, const Input& in) {
  frontend::FrontendParams params = config.core;
  if (o.no_deskew || in.point_times == io::PointTimes::kNone) params.deskew = false;
  if (o.no_imu_window) params.imu_window = false;
  if (o.imu_deskew) params.imu_deskew = true;
  if (o.no_level) params.level_with_gravity = false;
  params.T_lidar_imu = in.T_lidar_imu;
  return params;
}

// The odometry of every sweep and the keyframes, and the time spent in the core [s].
struct Run {
  geometry::Trajectory odometry, keyframes;
  double busy_s = 0;
};

Run run_core(frontend::FrontendCore& core, const Input& in, bool use_imu) {
  Run run;
  size_t imu_next = 0;
  const auto sweep_ns = static_cast<int64_t>(std::llround(in.sweep_period_s * 1e9));
  std::vector<frontend::ScanPoint> pts;
  for (const io::DatasetScan& s : in.scans) {
    pts.clear();
    for (const io::CloudPoint& p : io::read_dataset_scan(s).points)
      pts.push_back({Eigen::Vector3f(p.x, p.y, p.z), p.time_offset, p.ring});
    const auto t0 = std::chrono::steady_clock::now();
    while (use_imu && imu_next < in.imu.size() && in.imu[imu_next].stamp_ns <= s.stamp_ns + sweep_ns) {
      core.add_imu({in.imu[imu_next].stamp_ns, in.imu[imu_next].gyro, in.imu[imu_next].accel});
      ++imu_next;
    }
    const frontend::ScanOut o = core.process(s.stamp_ns, pts);
    run.busy_s += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    run.odometry.push_back({s.stamp_ns, o.T_odom_raw});
    if (o.keyframe) run.keyframes.push_back({o.keyframe->stamp_ns, o.keyframe->T_odom_keyframe});
  }
  return run;
}

nlohmann::json make_report(const Options& o, const Input& in, const Run& run, const frontend::FrontendStats& st,
                           bool use_imu, double wall_s) {
  return nlohmann::json{{"dataset", o.input},
                        {"scans", run.odometry.size()},
                        {"keyframes", run.keyframes.size()},
                        {"imu", use_imu},
                        {"point_times", io::to_string(in.point_times)},
                        {"scans_per_s", static_cast<double>(run.odometry.size()) / std::max(run.busy_s, 1e-9)},
                        {"scans_per_s_with_reading", static_cast<double>(run.odometry.size()) / std::max(wall_s, 1e-9)},
                        {"registration_failures", st.registration_failures},
                        {"registration_rejected", st.registration_rejected},
                        {"recovery_attempts", st.recovery_attempts},
                        {"recoveries", st.recoveries},
                        {"recoveries_global", st.recoveries_global},
                        {"imu_predictions", st.imu_predictions},
                        {"imu_window_restarts", st.imu_window_restarts},
                        {"max_level_deg", st.max_level_deg}};
}

// Drift, ATE and RPE per sweep against the ground truth, expressed from the first scan's pose like
// the odometry (nothing without ground truth).
void add_accuracy(nlohmann::json& report, const geometry::Trajectory& odometry,
                  const geometry::Trajectory& groundtruth) {
  if (groundtruth.empty() || odometry.empty()) return;
  const auto gt_at = [&](int64_t stamp) { return geometry::interpolate_at(groundtruth, stamp); };
  geometry::Poses est, gt;
  const auto first = gt_at(odometry.front().stamp_ns);
  for (const auto& sp : odometry) {
    const auto g = first ? gt_at(sp.stamp_ns) : std::nullopt;
    if (!g) continue;
    est.push_back(sp.pose);
    gt.push_back(first->inverse() * *g);
  }
  if (est.size() <= 20) return;
  const geometry::KittiDrift d = geometry::compute_kitti_drift(est, gt);
  const geometry::AteResult ate = geometry::compute_ate(est, gt, geometry::AlignMode::kSE3);
  report["drift_trans_pct"] = d.translation_pct;
  report["drift_rot_deg_per_100m"] = d.rotation_deg_per_100m;
  report["ate_m"] = ate.translation.rmse;
  const geometry::RpeResult rpe = geometry::compute_rpe_frames(est, gt, 1);
  report["rpe_per_sweep"] = {
      {"translation_m",
       {{"rmse", rpe.translation.rmse}, {"median", rpe.translation.median}, {"max", rpe.translation.max}}},
      {"rotation_deg",
       {{"rmse", rpe.rotation_deg.rmse}, {"median", rpe.rotation_deg.median}, {"max", rpe.rotation_deg.max}}}};
}

void write_outputs(const std::string& out_dir, const Run& run, const nlohmann::json& report) {
  fs::create_directories(out_dir);
  geometry::write_tum((fs::path(out_dir) / "odometry.tum").string(), run.odometry);
  geometry::write_kitti((fs::path(out_dir) / "odometry.kitti").string(), run.odometry);
  geometry::write_tum((fs::path(out_dir) / "keyframes.tum").string(), run.keyframes);
  std::ofstream(fs::path(out_dir) / "report.json") << report.dump(2) << '\n';
}

void print_summary(const std::string& input, const nlohmann::json& report) {
  std::cout << input << ": " << report["scans"].get<size_t>() << " scans, " << report["keyframes"].get<size_t>()
            << " keyframes, " << report["scans_per_s"].get<double>() << " scans/s";
  if (report.contains("ate_m")) {
    std::cout << "; drift " << report["drift_trans_pct"].get<double>() << " % / "
              << report["drift_rot_deg_per_100m"].get<double>() << " deg/100m, ATE " << report["ate_m"].get<double>()
              << " m";
  }
  std::cout << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-odometry: runs the front-end core over a recorded dataset without DDS and writes its trajectory.\n"
      "  cdc-odometry DATASET [--robot K]               a cdc-sim dataset folder (robot_K/...)\n"
      "  cdc-odometry DIR --kitti [--poses P]           a KITTI sequence or velodyne folder (no IMU, sweeps taken as\n"
      "                                                 motion-compensated); cdc-import makes a dataset of it"};
  Options o;
  add_options(app, o);
  CLI11_PARSE(app, argc, argv);
  return base::run_tool("cdc-odometry", [&] {
    const auto wall0 = std::chrono::steady_clock::now();
    const Input in = read_input(o);
    const frontend::FrontendNodeOptions config = frontend::load_frontend_options(o.config_path);
    frontend::FrontendCore core(core_params(config, o, in));
    const bool use_imu = !o.lidar_only && config.use_imu && !in.imu.empty();
    const Run run = run_core(core, in, use_imu);
    const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
    nlohmann::json report = make_report(o, in, run, core.stats(), use_imu, wall);
    add_accuracy(report, run.odometry, in.groundtruth);
    if (!o.out_dir.empty()) write_outputs(o.out_dir, run, report);
    if (o.json) {
      std::cout << report.dump() << '\n';
    } else {
      print_summary(o.input, report);
    }
    return 0;
  });
}
