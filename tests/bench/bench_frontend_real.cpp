// cdc-bench-frontend-real: the front-end core on real LiDAR sweeps saved as KITTI .bin files, without
// IMU and without per-point times (the sweeps are taken as they are: no deskewing, no invented times).
//
//   --sequence DIR [--poses P] [--times T] [--period S]
//       every DIR/*.bin in name order through one FrontendCore: sweeps tracked, registration failures
//       and rejections, recoveries, ATE against the reference poses (LiDAR frame, SE(3)-aligned), RPE
//       per sweep (translation and rotation: median, p90, max) and sweeps per second on one core with
//       reading included.
//   --speed [--data DIR] [--repeat N]
//       real HDL-64E sweeps (kitti/scans: the 6 consecutive ones of `unknown` and the two consecutive
//       pairs of sequence 00), each set through a fresh core, reading included, repeated N times:
//       median sweeps per second, and the error of the two pairs' relative motion against the ground
//       truth.
// The core runs with its defaults for a sensor without per-point times and without IMU (FrontendParams
// and frontend.yaml as they are: sweeps whose points carry no time are not deskewed). Last line: one
// JSON object.
#include "cdc/frontend/frontend_core.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/se3.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/kitti.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

namespace {

using namespace cdc;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

// CPU time of this thread [s]: what the run costs on one core, whatever else the machine runs.
double thread_cpu_s() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

std::vector<fs::path> list_bins(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".bin") files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

// A saved sweep as the core takes it: no per-point time, no ring.
std::vector<frontend::ScanPoint> read_sweep(const fs::path& file) {
  const std::vector<io::CloudPoint> cloud = io::read_kitti_bin(file);
  std::vector<frontend::ScanPoint> pts;
  pts.reserve(cloud.size());
  for (const io::CloudPoint& c : cloud) pts.push_back({Eigen::Vector3f(c.x, c.y, c.z), 0.0F, 0});
  return pts;
}

struct Timing {
  double wall_s = 0, cpu_s = 0;
};

// What the core said about one sweep (CDC_BENCH_VERBOSE).
struct ScanInfo {
  double fit = 0, fit_rms = 0;
  int fit_points = 0, correspondences = 0, iterations = 0;
  bool converged = false, recovered = false;
};

// printf into a string.
template <class... Args>
std::string format(const char* fmt, Args... args) {
  const int n = std::snprintf(nullptr, 0, fmt, args...);
  std::string out(static_cast<size_t>(std::max(n, 0)) + 1, '\0');
  std::snprintf(out.data(), out.size(), fmt, args...);
  out.pop_back();
  return out;
}

// One set of sweeps through a fresh core, each read from disk inside the timed span.
std::vector<Eigen::Isometry3d> run_set(const std::vector<fs::path>& files, const std::vector<int64_t>& stamps_ns,
                                       const frontend::FrontendParams& params, Timing& timing,
                                       frontend::FrontendStats* stats, std::vector<double>* per_sweep_s,
                                       std::vector<ScanInfo>* info = nullptr) {
  frontend::FrontendCore core(params);
  std::vector<Eigen::Isometry3d> poses;
  poses.reserve(files.size());
  const auto t0 = Clock::now();
  const double c0 = thread_cpu_s();
  for (size_t i = 0; i < files.size(); ++i) {
    const auto s0 = Clock::now();
    const std::vector<frontend::ScanPoint> pts = read_sweep(files[i]);
    const frontend::ScanOut o = core.process(stamps_ns[i], pts);
    poses.push_back(o.T_odom_raw);
    if (info != nullptr) {
      info->push_back({o.fit.inlier_fraction, o.fit.inlier_rms, o.fit.points, o.registration.correspondences,
                       o.registration.iterations, o.registration.converged, o.recovered});
    }
    if (per_sweep_s != nullptr) per_sweep_s->push_back(seconds_since(s0));
  }
  timing.wall_s += seconds_since(t0);
  timing.cpu_s += thread_cpu_s() - c0;
  if (stats != nullptr) *stats = core.stats();
  return poses;
}

// The error of an estimated relative motion against the true one: [m] and [deg].
std::pair<double, double> relative_error(const Eigen::Isometry3d& est, const Eigen::Isometry3d& truth) {
  const Eigen::Isometry3d e = truth.inverse() * est;
  return {e.translation().norm(), geometry::rotation_angle(e.rotation()) * 180.0 / M_PI};
}

nlohmann::json stats_json(const geometry::ErrorStats& s) {
  return {{"median", s.median}, {"p90", s.p90}, {"max", s.max}, {"rmse", s.rmse}};
}

int run_sequence(const fs::path& dir, std::string poses_path, std::string times_path, double period_s,
                 const frontend::FrontendParams& params, int repeat) {
  const std::vector<fs::path> files = list_bins(dir);
  if (files.empty()) throw std::runtime_error(dir.string() + ": no .bin sweeps");
  if (poses_path.empty() && fs::exists(dir / "poses.txt")) poses_path = (dir / "poses.txt").string();
  if (times_path.empty() && fs::exists(dir / "times.txt")) times_path = (dir / "times.txt").string();
  std::vector<int64_t> stamps;
  if (!times_path.empty()) {
    stamps = geometry::read_times(times_path);
    if (stamps.size() < files.size()) {
      throw std::runtime_error(times_path + ": " + std::to_string(stamps.size()) + " times for " +
                               std::to_string(files.size()) + " sweeps");
    }
    stamps.resize(files.size());
  } else {
    for (size_t i = 0; i < files.size(); ++i)
      stamps.push_back(static_cast<int64_t>(static_cast<double>(i) * period_s * 1e9));
  }
  // Repeats only for the speed figure: every run of a core over the same sweeps gives the same poses.
  std::vector<double> rates, cpu_rates, per_sweep;
  std::vector<ScanInfo> info;
  frontend::FrontendStats st;
  std::vector<Eigen::Isometry3d> est;
  for (int r = 0; r < repeat; ++r) {
    Timing t;
    est = run_set(files, stamps, params, t, &st, r == 0 ? &per_sweep : nullptr, r == 0 ? &info : nullptr);
    rates.push_back(static_cast<double>(files.size()) / t.wall_s);
    cpu_rates.push_back(static_cast<double>(files.size()) / t.cpu_s);
  }
  const geometry::ErrorStats rate = geometry::compute_stats(rates), cpu_rate = geometry::compute_stats(cpu_rates);
  const geometry::ErrorStats sweep_s = geometry::compute_stats(per_sweep);
  nlohmann::json j{
      {"mode", "sequence"},
      {"sequence", dir.string()},
      {"sweeps", files.size()},
      {"registration_failures", st.registration_failures},
      {"registration_rejected", st.registration_rejected},
      {"recoveries", st.recoveries},
      {"recovery_attempts", st.recovery_attempts},
      {"recoveries_global", st.recoveries_global},
      {"sweeps_per_s", rate.median},
      {"sweeps_per_cpu_s", cpu_rate.median},
      {"sweep_ms", {{"median", 1e3 * sweep_s.median}, {"p90", 1e3 * sweep_s.p90}, {"max", 1e3 * sweep_s.max}}},
      {"repeat", repeat}};
  std::string summary = format(
      "%s: %zu sweeps, %llu registration failures (%llu rejected), %llu recoveries (%llu global), %.1f "
      "sweeps/s (%.1f per CPU s)",
      dir.string().c_str(), files.size(), static_cast<unsigned long long>(st.registration_failures),
      static_cast<unsigned long long>(st.registration_rejected), static_cast<unsigned long long>(st.recoveries),
      static_cast<unsigned long long>(st.recoveries_global), rate.median, cpu_rate.median);
  if (!poses_path.empty()) {
    const geometry::Trajectory ref = geometry::read_kitti(poses_path);
    if (ref.size() < files.size()) {
      throw std::runtime_error(poses_path + ": " + std::to_string(ref.size()) + " poses for " +
                               std::to_string(files.size()) + " sweeps");
    }
    geometry::Poses gt;
    for (size_t i = 0; i < files.size(); ++i) gt.push_back(ref[i].pose);
    const geometry::AteResult ate = geometry::compute_ate(est, gt, geometry::AlignMode::kSE3);
    const geometry::RpeResult rpe = geometry::compute_rpe_frames(est, gt, 1);
    if (std::getenv("CDC_BENCH_VERBOSE") != nullptr) {
      for (size_t i = 1; i < files.size(); ++i) {
        const Eigen::Isometry3d d_ref = gt[i - 1].inverse() * gt[i], d_est = est[i - 1].inverse() * est[i];
        const auto [et, er] = relative_error(d_est, d_ref);
        const ScanInfo& in = info[i];
        std::printf(
            "sweep %3zu: reference %.2f m %5.1f deg, estimated %.2f m %5.1f deg, error %.3f m %5.2f deg; fit %.3f (%d "
            "points, "
            "rms %.3f m), %d correspondences, %d iterations%s%s\n",
            i, d_ref.translation().norm(), geometry::rotation_angle(d_ref.rotation()) * 180 / M_PI,
            d_est.translation().norm(), geometry::rotation_angle(d_est.rotation()) * 180 / M_PI, et, er, in.fit,
            in.fit_points, in.fit_rms, in.correspondences, in.iterations, in.recovered ? ", recovered" : "",
            in.converged ? "" : ", NOT CONVERGED");
      }
    }
    j["ate_m"] = ate.translation.rmse;
    j["ate_max_m"] = ate.translation.max;
    j["ate_rot_deg"] = ate.rotation_deg.rmse;
    j["rpe_m"] = stats_json(rpe.translation);
    j["rpe_deg"] = stats_json(rpe.rotation_deg);
    summary += format(
        "; ATE %.3f m (max %.3f m); RPE per sweep %.3f / %.3f / %.3f m, %.2f / %.2f / %.2f deg (median / p90 / max)",
        ate.translation.rmse, ate.translation.max, rpe.translation.median, rpe.translation.p90, rpe.translation.max,
        rpe.rotation_deg.median, rpe.rotation_deg.p90, rpe.rotation_deg.max);
  }
  std::cout << summary << '\n' << j.dump() << '\n';
  return 0;
}

int run_speed(const fs::path& data, int repeat, const frontend::FrontendParams& params) {
  const fs::path scans = data / "kitti" / "scans";
  struct Set {
    std::string name;
    std::vector<fs::path> files;
    std::optional<Eigen::Isometry3d> truth;  // second sweep relative to the first, LiDAR frame
  };
  std::vector<Set> sets;
  sets.push_back({"unknown", list_bins(scans / "unknown"), std::nullopt});
  const fs::path poses = data / "kitti" / "poses" / "00.txt", calib = data / "kitti" / "calib_Tr.txt";
  const geometry::Trajectory gt =
      io::kitti_lidar_trajectory(poses.string(), io::read_kitti_calib(calib.string(), "Tr_00_02"));
  for (size_t first : {size_t{94}, size_t{198}}) {
    Set s{"seq00_" + std::to_string(first), {}, std::nullopt};
    for (size_t k : {first, first + 1}) {
      char name[16];
      std::snprintf(name, sizeof name, "%06zu.bin", k);
      s.files.push_back(scans / "seq00" / name);
      if (!fs::exists(s.files.back())) throw std::runtime_error(s.files.back().string() + ": not found");
    }
    if (gt.size() <= first + 1)
      throw std::runtime_error(poses.string() + ": fewer than " + std::to_string(first + 2) + " poses");
    s.truth = gt[first].pose.inverse() * gt[first + 1].pose;
    sets.push_back(std::move(s));
  }
  if (sets.front().files.size() != 6) {
    throw std::runtime_error((scans / "unknown").string() + ": " + std::to_string(sets.front().files.size()) +
                             " sweeps, expected 6");
  }
  size_t per_round = 0;
  for (const Set& s : sets) per_round += s.files.size();
  std::vector<double> rates, cpu_rates;
  nlohmann::json pairs = nlohmann::json::object();
  uint64_t failures = 0;
  for (int r = 0; r < repeat; ++r) {
    Timing t;
    for (const Set& s : sets) {
      std::vector<int64_t> stamps;
      for (size_t i = 0; i < s.files.size(); ++i) stamps.push_back(static_cast<int64_t>(i) * 100'000'000);
      frontend::FrontendStats st;
      const std::vector<Eigen::Isometry3d> est = run_set(s.files, stamps, params, t, &st, nullptr);
      if (r > 0) continue;
      failures += st.registration_failures;
      if (s.truth) {
        const auto [dt, dr] = relative_error(est[0].inverse() * est[1], *s.truth);
        pairs[s.name] = {{"error_m", dt}, {"error_deg", dr}, {"motion_m", s.truth->translation().norm()}};
      }
    }
    rates.push_back(static_cast<double>(per_round) / t.wall_s);
    cpu_rates.push_back(static_cast<double>(per_round) / t.cpu_s);
  }
  const geometry::ErrorStats rate = geometry::compute_stats(rates), cpu_rate = geometry::compute_stats(cpu_rates);
  std::printf(
      "real HDL-64E sweeps (%zu a round, %d rounds, reading included): %.1f sweeps/s median (%.1f per CPU s; min %.1f, "
      "max %.1f); %llu registration failures; pair errors",
      per_round, repeat, rate.median, cpu_rate.median, rate.min, rate.max, static_cast<unsigned long long>(failures));
  for (const auto& [name, e] : pairs.items()) {
    std::printf(" %s %.3f m %.3f deg", name.c_str(), e["error_m"].get<double>(), e["error_deg"].get<double>());
  }
  std::printf("\n");
  const nlohmann::json j{{"mode", "speed"},
                         {"sweeps_per_round", per_round},
                         {"repeat", repeat},
                         {"sweeps_per_s", rate.median},
                         {"sweeps_per_cpu_s", cpu_rate.median},
                         {"sweeps_per_s_min", rate.min},
                         {"sweeps_per_s_max", rate.max},
                         {"registration_failures", failures},
                         {"pairs", pairs}};
  std::cout << j.dump() << '\n';
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-bench-frontend-real: the front-end core on real saved sweeps (KITTI .bin; no IMU, no per-point times).\n"
      "  --sequence DIR [--poses P] [--times T] [--period S]   a folder of consecutive sweeps (LiDAR-frame reference\n"
      "                                                         poses: ATE, RPE per sweep), tracking and speed\n"
      "  --speed [--data DIR] [--repeat N]                      speed on the real HDL-64E sweeps of DIR/kitti/scans"};
  const char* env = std::getenv("CDC_DATA_DIR");
  std::string data = env != nullptr ? env : "../shared/data", sequence, poses, times;
  double period_s = 0.1;
  int repeat = 0;
  bool speed = false;
  app.add_option("--sequence", sequence, "folder of KITTI .bin sweeps, in name order")->check(CLI::ExistingDirectory);
  app.add_option("--poses", poses, "reference poses of the LiDAR, KITTI 3x4 (default: DIR/poses.txt if present)")
      ->check(CLI::ExistingFile);
  app.add_option("--times", times, "sweep times in seconds, one a line (default: DIR/times.txt if present)")
      ->check(CLI::ExistingFile);
  app.add_option("--period", period_s, "seconds between sweeps without a times file")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_flag("--speed", speed, "speed on the real HDL-64E sweeps of DATA/kitti/scans");
  app.add_option("--data", data, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  app.add_option("--repeat", repeat, "rounds (default: 1 for --sequence, 20 for --speed); the median speed is reported")
      ->check(CLI::PositiveNumber);
  frontend::FrontendParams params;
  bool no_recovery = false, no_global = false;
  app.add_option("--normal-voxel", params.normal_voxel_m,
                 "sweeps reduced to one point per voxel of this size before their normals [m] (for comparison)")
      ->capture_default_str();
  app.add_flag("--no-recovery", no_recovery, "no recovery of poor registrations (for comparison)");
  app.add_flag("--no-global", no_global, "recovery without global registration (for comparison)");
  CLI11_PARSE(app, argc, argv);
  params.recovery.enabled = !no_recovery;
  params.recovery.global = !no_global;
  if (speed == !sequence.empty()) {
    std::cerr << "cdc-bench-frontend-real: give exactly one of --sequence DIR and --speed (see --help)\n";
    return 2;
  }
  try {
    if (speed) {
      if (!fs::exists(fs::path(data) / "kitti" / "scans")) {
        std::cerr << "cdc-bench-frontend-real: " << data << "/kitti/scans not found (set --data or CDC_DATA_DIR)\n";
        return 2;
      }
      return run_speed(data, repeat > 0 ? repeat : 20, params);
    }
    return run_sequence(sequence, poses, times, period_s, params, repeat > 0 ? repeat : 1);
  } catch (const std::exception& e) {
    std::cerr << "cdc-bench-frontend-real: " << e.what() << '\n';
    return 1;
  }
}
