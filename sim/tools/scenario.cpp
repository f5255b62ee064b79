#include "scenario.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/io/dataset.hpp"
#include "cdc/io/kitti.hpp"
#include "cdc/sim/trajectory.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <stdexcept>

namespace cdc::sim {
namespace fs = std::filesystem;

namespace {
// The longest mission and the longest span a scenario may ask for: two hours of every robot's sensors is
// already tens of GB of sweeps, and the trajectories and the radio timeline grow with it.
constexpr double kMaxDurationS = 7200;
}  // namespace

LidarModel scenario_lidar(const Scenario& s, int robot) {
  LidarModel model = s.lidar == "hdl64" ? LidarModel::hdl64() : LidarModel::vlp16();
  // One calibration error per beam, drawn from the seed: the same sensor model on every robot, or with
  // lidar_per_robot each robot's own unit. Each kind of error has its own stream, so adding one leaves the
  // others' draws (and older datasets) unchanged.
  uint64_t unit = 0;
  if (s.lidar_per_robot) unit = uint64_t{1000003} * static_cast<uint64_t>(robot + 1);
  auto per_beam = [&](double sigma, uint64_t stream) {
    std::mt19937_64 cal(s.seed * 7919 + stream + unit);
    std::normal_distribution<double> err(0.0, sigma);
    std::vector<double> v(model.elevations_deg.size());
    for (double& e : v) e = err(cal);
    return v;
  };
  if (s.lidar_elevation_error_deg > 0 || s.lidar_elevation_bias_deg != 0) {
    // The per-beam spread plus the error common to all beams.
    model.elevation_error_deg.assign(model.elevations_deg.size(), s.lidar_elevation_bias_deg);
    if (s.lidar_elevation_error_deg > 0) {
      const std::vector<double> spread = per_beam(s.lidar_elevation_error_deg, 17);
      for (size_t b = 0; b < spread.size(); ++b) model.elevation_error_deg[b] += spread[b];
    }
  }
  if (s.lidar_azimuth_error_deg > 0) model.azimuth_error_deg = per_beam(s.lidar_azimuth_error_deg, 29);
  if (s.lidar_range_offset_m > 0) model.range_offset_m = per_beam(s.lidar_range_offset_m, 43);
  return model;
}

namespace {

// The radio timeline holds one sample per pair of nodes per 0.1 s of the mission: a limit on their number keeps
// a scenario within memory (a sample is 48 bytes). The span is the mission's, or duration_s when shorter;
// KITTI sequences are bounded by their data.
void check_timeline_size(config::Reader& r, const Scenario& s) {
  constexpr double kMaxLinkSamples = 2e7;
  double span = s.source == "procedural" ? s.mission.duration_s : 0;
  if (s.duration_s > 0) span = span > 0 ? std::min(span, s.duration_s) : s.duration_s;
  const double nodes = s.robots + 1.0;
  const double samples = nodes * (nodes - 1) / 2 * (span / 0.1);
  if (samples > kMaxLinkSamples) {
    char text[200];
    std::snprintf(text, sizeof text,
                  "%d robots over %.0f s make a radio timeline of %.3g link samples, more than the %.0g allowed "
                  "(fewer robots or a shorter duration_s)",
                  s.robots, span, samples, kMaxLinkSamples);
    r.error(text);
  }
}

}  // namespace

Scenario load_scenario(const std::string& path) {
  Scenario s;
  if (!fs::exists(path)) {
    throw config::ConfigError(path + ": scenario file not found");
  }
  config::Reader r(path);
  r.get<std::string>("name", s.name);
  r.get<uint64_t>("seed", s.seed);  // every uint64 is a seed
  r.get<std::string>(
      "trajectories.source", s.source, [](const std::string& v) { return v == "kitti" || v == "procedural"; },
      "kitti or procedural");
  r.get<std::string>("trajectories.sequence", s.kitti_sequence);
  r.get<std::string>("trajectories.calib_key", s.calib_key);
  r.get_in("trajectories.robots", s.robots, 1, 64);
  r.get_in("trajectories.overlap", s.overlap, 0.0, 0.9);
  r.get_in("trajectories.time_shift_s", s.time_shift_s, 0.0, kMaxDurationS);
  r.get<std::vector<int>>(
      "trajectories.reverse", s.reverse,
      [](const std::vector<int>& v) { return std::all_of(v.begin(), v.end(), [](int k) { return k >= 0 && k < 64; }); },
      "a list of robot numbers");
  r.get_in("trajectories.reverse_lane_m", s.reverse_lane_m, -20.0, 20.0);
  std::string pattern = "rays";
  r.get<std::string>(
      "trajectories.pattern", pattern, [](const std::string& v) { return parse_pattern(v).has_value(); },
      "rays, loops or crossing");
  s.mission.pattern = parse_pattern(pattern).value_or(MissionPattern::kRays);
  r.get_in("trajectories.speed_mps", s.mission.speed_mps, 0.1, 50.0);
  r.get_in("trajectories.size_m", s.mission.size_m, 1.0, 1e5);
  r.get_in("trajectories.duration_s", s.mission.duration_s, 1.0, kMaxDurationS);
  s.mission.robots = s.robots;
  r.get<std::string>(
      "lidar", s.lidar, [](const std::string& v) { return v == "vlp16" || v == "hdl64"; }, "vlp16 or hdl64");
  r.get_in("lidar_elevation_error_deg", s.lidar_elevation_error_deg, 0.0, 2.0);  // a sigma
  r.get_in("lidar_elevation_bias_deg", s.lidar_elevation_bias_deg, -1.0, 1.0);
  r.get_in("lidar_azimuth_error_deg", s.lidar_azimuth_error_deg, 0.0, 2.0);  // a sigma
  r.get_in("lidar_range_offset_m", s.lidar_range_offset_m, 0.0, 0.2);        // a sigma
  r.get<bool>("lidar_per_robot", s.lidar_per_robot);
  r.get_in("imu_rate_hz", s.imu_rate_hz, 100.0, 400.0);
  r.get_in("duration_s", s.duration_s, 0.0, kMaxDurationS);
  r.get<int>(
      "radio.central_robot", s.central_robot, [](const int& v) { return v >= -1 && v <= 63; }, "-1 or a robot id");
  std::array<double, 3> cp{0, 0, 0};
  r.get_position("radio.central_position", cp);
  s.central_position = Eigen::Vector3d(cp[0], cp[1], cp[2]);
  r.get_in("radio.central_id", s.central_id, 0u, 254u);
  r.get_in("radio.central_range_m", s.central_range_m, 1.0, 1e6);
  r.get_in("radio.robot_range_m", s.robot_range_m, 1.0, 1e6);
  r.get_in("radio.loss_start_fraction", s.radio.loss_start_fraction, 0.01, 1.0);
  r.get_in("radio.max_loss", s.radio.max_loss, 0.0, 1.0);
  r.get_in("world.clearance_m", s.world.clearance_m, 0.1, 100.0);
  r.get_in("world.spacing_m", s.world.spacing_m, 1.0, 1000.0);
  s.world.seed = s.seed;
  for (int k : s.reverse) {
    if (k >= s.robots) {
      r.error("trajectories.reverse: robot " + std::to_string(k) + " is not one of the " + std::to_string(s.robots) +
              " robots");
    }
  }
  if (!s.reverse.empty() && s.source != "kitti") r.error("trajectories.reverse applies to KITTI sources only");
  if (s.central_robot >= s.robots) {
    r.error("radio.central_robot " + std::to_string(s.central_robot) + " is not one of the " +
            std::to_string(s.robots) + " robots");
  }
  check_timeline_size(r, s);
  if (s.central_id < static_cast<uint32_t>(s.robots)) {
    r.error("radio.central_id " + std::to_string(s.central_id) + " collides with a robot id");
  }
  r.finish();
  return s;
}

namespace {

void write_file(const fs::path& p, const void* data, size_t bytes) {
  std::ofstream out(p, std::ios::binary);
  if (!out || !out.write(static_cast<const char*>(data), static_cast<std::streamsize>(bytes))) {
    throw std::runtime_error(p.string() + ": cannot write");
  }
}

void write_text(const fs::path& p, const std::string& text) { write_file(p, text.data(), text.size()); }

std::vector<geometry::Trajectory> robot_trajectories(const Scenario& s, const GenerateOptions& g) {
  if (s.source == "procedural") {
    return procedural_mission(s.mission);
  }
  const fs::path poses = fs::path(g.data_dir) / "kitti" / "poses" / (s.kitti_sequence + ".txt");
  const fs::path calib = fs::path(g.data_dir) / "kitti" / "calib_Tr.txt";
  for (const auto& p : {poses, calib}) {
    if (!fs::exists(p)) {
      throw std::runtime_error(p.string() + ": reference data not found (set --data or CDC_DATA_DIR)");
    }
  }
  const auto seq = io::kitti_lidar_trajectory(poses.string(), io::read_kitti_calib(calib.string(), s.calib_key));
  io::SplitOptions split;
  split.robots = s.robots;
  split.overlap = s.overlap;
  split.time_shift_s = s.time_shift_s;
  split.reverse = s.reverse;
  split.reverse_lane_m = s.reverse_lane_m;
  return io::split_robots(seq, split);
}

SplineTrajectory to_spline(const geometry::Trajectory& t) {
  std::vector<Eigen::Isometry3d> c;
  for (const auto& sp : t) {
    c.push_back(sp.pose);
  }
  return SplineTrajectory(c, static_cast<double>(t.front().stamp_ns) * 1e-9, 0.1);
}

std::vector<RadioNode> radio_nodes(const Scenario& s, const std::vector<SplineTrajectory>& splines) {
  std::vector<RadioNode> nodes;
  for (size_t r = 0; r < splines.size(); ++r) {
    const SplineTrajectory* sp = &splines[r];
    nodes.push_back({static_cast<uint32_t>(r), s.robot_range_m,
                     [sp](double t) { return Eigen::Vector3d(sp->pose(t).translation()); }});
  }
  if (s.central_robot >= 0) {
    const SplineTrajectory* sp = &splines[static_cast<size_t>(s.central_robot)];
    nodes.push_back(
        {s.central_id, s.central_range_m, [sp](double t) { return Eigen::Vector3d(sp->pose(t).translation()); }});
  } else {
    const Eigen::Vector3d c = s.central_position;
    nodes.push_back({s.central_id, s.central_range_m, [c](double) { return c; }});
  }
  return nodes;
}

}  // namespace

std::vector<OutOfRangePeriod> scenario_radio_periods(const Scenario& s, const GenerateOptions& g) {
  std::vector<SplineTrajectory> splines;
  double t0 = 1e18, t1 = 0;
  for (const auto& t : robot_trajectories(s, g)) {
    splines.push_back(to_spline(t));
    t0 = std::min(t0, splines.back().start());
    double e = splines.back().end() - 0.1;
    if (s.duration_s > 0) {
      e = std::min(e, splines.back().start() + s.duration_s);
    }
    t1 = std::max(t1, e);
  }
  RadioOptions radio = s.radio;
  radio.stop = g.stop;
  return out_of_range_periods(radio_timeline(radio_nodes(s, splines), t0, t1, radio));
}

GenerateSummary generate_dataset(const Scenario& s, const std::string& scenario_path, const std::string& out_dir,
                                 const GenerateOptions& g) {
  GenerateSummary sum;
  const auto trajectories = robot_trajectories(s, g);
  std::vector<SplineTrajectory> splines;
  std::vector<std::vector<Eigen::Vector3d>> paths;
  for (const auto& t : trajectories) {
    splines.push_back(to_spline(t));
    std::vector<Eigen::Vector3d> path;
    for (const auto& sp : t) {
      path.push_back(sp.pose.translation());
    }
    paths.push_back(path);
  }
  const World world = World::generate(paths, s.world);
  Eigen::Isometry3d T_lidar_imu = Eigen::Isometry3d::Identity();  // the IMU sits 10 cm behind, 5 cm below
  T_lidar_imu.translation() = Eigen::Vector3d(-0.10, 0.0, -0.05);

  io::DatasetWriter writer(out_dir, /*overwrite=*/true);
  double t_end_all = 0, t_start_all = 1e18;
  for (size_t r = 0; r < splines.size(); ++r) {
    const SplineTrajectory& sp = splines[r];
    const auto robot = static_cast<uint32_t>(r);
    const LidarModel model = scenario_lidar(s, static_cast<int>(r));
    std::mt19937_64 rng(s.seed * 1000 + r);
    // Margins at both ends: derivatives of the spline (IMU) look a little before and after.
    const double t_first = sp.start() + 0.1;
    double t_end = sp.end() - 2 * model.period_s();
    if (s.duration_s > 0) {
      t_end = std::min(t_end, t_first + s.duration_s);
    }
    geometry::Trajectory gt;
    size_t k = 0;
    for (double t = t_first; t <= t_end + 1e-9; t = t_first + 0.1 * static_cast<double>(++k)) {
      if (g.max_scans > 0 && k >= g.max_scans) {
        break;
      }
      if (g.stop && g.stop()) throw Stopped();
      io::Sweep out;
      out.has_time = out.has_ring = out.has_intensity = true;
      for (const auto& p : sweep(
               world, model, [&](double tau) { return sp.pose(t + tau); }, rng)) {
        out.points.push_back({p.x, p.y, p.z, p.intensity, p.time_offset, p.ring});
      }
      const auto stamp = static_cast<int64_t>(std::llround(t * 1e9));
      writer.add_sweep(robot, stamp, out);
      gt.push_back({stamp, sp.pose(t)});
      sum.points += out.points.size();
      ++sum.scans;
    }
    writer.set_groundtruth(robot, gt);
    // IMU over the scanned span, in the IMU frame mounted at T_lidar_imu on the LiDAR (the body).
    const double t_imu_start = t_first - 0.05;
    const double t_imu_end = gt.empty() ? t_first : static_cast<double>(gt.back().stamp_ns) * 1e-9 + model.period_s();
    std::vector<io::DatasetImu> imu;
    for (const auto& m :
         simulate_imu(sp, T_lidar_imu, t_imu_start, t_imu_end, s.imu_rate_hz, ImuNoise{}, s.seed * 1000 + 500 + r)) {
      imu.push_back({static_cast<int64_t>(std::llround(m.t * 1e9)), m.accel, m.gyro});
    }
    writer.set_imu(robot, imu);
    writer.set_calib(robot, T_lidar_imu, model.name, s.imu_rate_hz);
    t_start_all = std::min(t_start_all, t_imu_start);
    t_end_all = std::max(t_end_all, t_imu_end);
    ++sum.robots;
  }

  // Radio: robots and the central node.
  RadioOptions radio = s.radio;
  radio.stop = g.stop;
  const auto timeline = radio_timeline(radio_nodes(s, splines), t_start_all, t_end_all, radio);
  std::string periods = "a,b,start,end\n";
  for (const auto& p : out_of_range_periods(timeline)) {
    char line[96];
    std::snprintf(line, sizeof line, "%u,%u,%.3f,%.3f\n", p.a, p.b, p.start, p.end);
    periods += line;
    ++sum.out_of_range_periods;
  }
  writer.set_radio(radio_csv(timeline), periods);
  char world_json[256];
  std::snprintf(
      world_json, sizeof world_json,
      "{\"seed\": %llu, \"boxes\": %zu, \"cylinders\": %zu, \"terrain\": {\"cells\": [%d, %d], \"cell_m\": %g}}\n",
      static_cast<unsigned long long>(s.seed), world.boxes().size(), world.cylinders().size(), world.terrain().nx,
      world.terrain().ny, world.terrain().cell);
  write_text(writer.partial_dir() / "world.json", world_json);
  fs::copy_file(scenario_path, writer.partial_dir() / "scenario.yaml", fs::copy_options::overwrite_existing);
  io::DatasetInfo info;
  info.name = s.name;
  info.source = "simulated";
  info.central_id = s.central_id;
  info.out_of_range_periods = sum.out_of_range_periods;
  info.point_times = io::PointTimes::kSensor;
  info.sweep_period_s = 0.1;
  info.radio = "simulated";
  info.poses = "ground_truth";
  writer.commit(info);
  return sum;
}

}  // namespace cdc::sim
