#include "cdc/io/dataset.hpp"

#include "cdc/base/names.hpp"
#include "cdc/io/error.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <system_error>

namespace cdc::io {
namespace fs = std::filesystem;
namespace {

constexpr std::array<base::Named<PointTimes>, 3> kPointTimesNames{
    {{PointTimes::kSensor, "sensor"}, {PointTimes::kAzimuth, "azimuth"}, {PointTimes::kNone, "none"}}};

std::string sweep_name(size_t k) {
  char name[32];
  std::snprintf(name, sizeof name, "%06zu.bin", k);
  return name;
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::trunc);
  if (!out) throw std::runtime_error(p.string() + ": cannot write");
  out << text;
  if (!out) throw std::runtime_error(p.string() + ": write failed");
}

// A count or id in dataset.json: a JSON integer within T's range (absent: `fallback`). A float or a
// negative number would otherwise be cast to T unchecked.
template <class T>
T integer_field(const nlohmann::json& j, const char* key, T fallback, const fs::path& p) {
  const auto it = j.find(key);
  if (it == j.end()) return fallback;
  constexpr uint64_t kMax = std::numeric_limits<T>::max();
  if ((it->is_number_unsigned() && it->get<uint64_t>() <= kMax) ||
      (it->is_number_integer() && it->get<int64_t>() >= 0 && static_cast<uint64_t>(it->get<int64_t>()) <= kMax)) {
    return static_cast<T>(it->get<uint64_t>());
  }
  throw FormatError(p.string() + ": " + key + " must be an integer in [0, " + std::to_string(kMax) + "], found " +
                    it->dump());
}

}  // namespace

const char* to_string(PointTimes t) { return base::name_of(kPointTimesNames, t, "sensor"); }

std::optional<PointTimes> parse_point_times(const std::string& s) { return base::value_of(kPointTimesNames, s); }

DatasetInfo read_dataset_info(const fs::path& dir) {
  const fs::path p = dir / "dataset.json";
  std::ifstream in(p);
  if (!in) throw FormatError(p.string() + ": cannot open (not a dataset folder?)");
  DatasetInfo info;
  try {
    const nlohmann::json j = nlohmann::json::parse(in);
    info.name = j.value("name", info.name);
    info.source = j.value("source", info.source);
    info.robots = integer_field(j, "robots", info.robots, p);
    info.scans = integer_field(j, "scans", info.scans, p);
    info.points = integer_field(j, "points", info.points, p);
    info.central_id = integer_field(j, "central_id", info.central_id, p);
    info.out_of_range_periods = integer_field(j, "out_of_range_periods", info.out_of_range_periods, p);
    info.sweep_period_s = j.value("sweep_period_s", info.sweep_period_s);
    info.radio = j.value("radio", info.radio);
    info.poses = j.value("poses", info.poses);
    const std::string times = j.value("point_times", std::string(to_string(info.point_times)));
    const auto t = parse_point_times(times);
    if (!t) throw FormatError(p.string() + ": point_times '" + times + "' is not sensor, azimuth or none");
    info.point_times = *t;
  } catch (const nlohmann::json::exception& e) {
    throw FormatError(p.string() + ": " + e.what());
  }
  if (!(info.sweep_period_s > 0)) throw FormatError(p.string() + ": sweep_period_s must be positive");
  return info;
}

void write_dataset_info(const fs::path& dir, const DatasetInfo& info) {
  const nlohmann::ordered_json j{{"name", info.name},
                                 {"source", info.source},
                                 {"robots", info.robots},
                                 {"scans", info.scans},
                                 {"points", info.points},
                                 {"central_id", info.central_id},
                                 {"out_of_range_periods", info.out_of_range_periods},
                                 {"point_times", to_string(info.point_times)},
                                 {"sweep_period_s", info.sweep_period_s},
                                 {"radio", info.radio},
                                 {"poses", info.poses}};
  write_text(dir / "dataset.json", j.dump(2) + "\n");
}

std::vector<DatasetImu> read_dataset_imu(const fs::path& p) {
  std::vector<DatasetImu> out;
  if (!fs::exists(p)) return out;
  std::ifstream in(p);
  if (!in) throw FormatError(p.string() + ": cannot open");
  std::string line;
  size_t n = 0;
  std::getline(in, line);
  ++n;
  while (std::getline(in, line)) {
    ++n;
    double t, a[3], g[3];
    if (std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf,%lf", &t, a, a + 1, a + 2, g, g + 1, g + 2) != 7) {
      throw FormatError(p.string() + ":" + std::to_string(n) + ": expected t,ax,ay,az,gx,gy,gz");
    }
    const double values[7] = {t, a[0], a[1], a[2], g[0], g[1], g[2]};
    if (!std::all_of(std::begin(values), std::end(values), [](double v) { return std::isfinite(v); })) {
      throw FormatError(p.string() + ":" + std::to_string(n) + ": a value is not a finite number");
    }
    out.push_back({static_cast<int64_t>(std::llround(t * 1e9)), Eigen::Vector3d(a[0], a[1], a[2]),
                   Eigen::Vector3d(g[0], g[1], g[2])});
    if (out.size() > 1 && out.back().stamp_ns <= out[out.size() - 2].stamp_ns) {
      throw FormatError(p.string() + ":" + std::to_string(n) + ": time does not increase");
    }
  }
  return out;
}

Eigen::Isometry3d read_dataset_calib(const fs::path& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (!fs::exists(p)) return T;
  // calib.yaml is one flow mapping per line; only T_lidar_imu's two lists matter here.
  std::ifstream in(p);
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.rfind("T_lidar_imu:", 0) != 0) continue;
    double t[3], q[4];
    const size_t a = line.find("position:");
    const size_t b = line.find("orientation:");
    if (a == std::string::npos || b == std::string::npos ||
        std::sscanf(line.c_str() + a, "position: [%lf, %lf, %lf]", t, t + 1, t + 2) != 3 ||
        std::sscanf(line.c_str() + b, "orientation: [%lf, %lf, %lf, %lf]", q, q + 1, q + 2, q + 3) != 4) {
      throw FormatError(p.string() + ":" + std::to_string(n) +
                        ": T_lidar_imu needs position: [x, y, z] and orientation: [x, y, z, w]");
    }
    if (!std::all_of(t, t + 3, [](double v) { return std::isfinite(v); }) ||
        !std::all_of(q, q + 4, [](double v) { return std::isfinite(v); })) {
      throw FormatError(p.string() + ":" + std::to_string(n) +
                        ": T_lidar_imu holds a value that is not a finite number");
    }
    const Eigen::Quaterniond quat(q[3], q[0], q[1], q[2]);
    if (std::abs(quat.norm() - 1.0) > 1e-3)
      throw FormatError(p.string() + ":" + std::to_string(n) + ": orientation is not a unit quaternion");
    T.linear() = quat.normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    return T;
  }
  throw FormatError(p.string() + ": no T_lidar_imu");
}

namespace {

// times.txt has one line per sweep: a folder holding more sweeps than lines (or fewer) is refused, so that a
// reader never plays part of a robot's sweeps without a word.
void check_sweep_count(const fs::path& robot_dir, size_t times) {
  size_t sweeps = 0;
  if (fs::is_directory(robot_dir / "velodyne")) {
    for (const auto& e : fs::directory_iterator(robot_dir / "velodyne")) {
      if (e.path().extension() == ".bin") ++sweeps;
    }
  }
  if (sweeps != times) {
    throw FormatError((robot_dir / "times.txt").string() + ": lists " + std::to_string(times) + " sweeps but " +
                      (robot_dir / "velodyne").string() + " holds " + std::to_string(sweeps));
  }
}

}  // namespace

std::vector<DatasetScan> list_dataset_scans(const std::string& dir, size_t max_scans,
                                            std::map<uint32_t, geometry::Trajectory>* groundtruth) {
  std::vector<DatasetScan> scans;
  for (uint32_t r = 0;; ++r) {
    const fs::path rd = fs::path(dir) / ("robot_" + std::to_string(r));
    if (!fs::is_directory(rd)) {
      if (r == 0) throw std::runtime_error(rd.string() + ": missing (no robot folders in " + dir + ")");
      break;
    }
    const std::vector<int64_t> times = geometry::read_times((rd / "times.txt").string());
    geometry::Trajectory gt;
    if (fs::exists(rd / "groundtruth.tum")) gt = geometry::read_tum((rd / "groundtruth.tum").string());
    const bool has_meta = fs::is_directory(rd / "velodyne_meta");
    for (size_t k = 0; k < times.size() && (max_scans == 0 || k < max_scans); ++k) {
      const std::string name = sweep_name(k);
      DatasetScan s{times[k],    r, k, rd / "velodyne" / name, has_meta ? rd / "velodyne_meta" / name : fs::path(),
                    std::nullopt};
      if (!fs::exists(s.bin))
        throw std::runtime_error(s.bin.string() + ": missing (times.txt lists " + std::to_string(times.size()) +
                                 " sweeps)");
      if (k < gt.size()) s.truth = gt[k].pose;
      scans.push_back(std::move(s));
    }
    check_sweep_count(rd, times.size());  // after the loop: a sweep it found missing is named there
    if (groundtruth != nullptr) (*groundtruth)[r] = gt;
  }
  std::stable_sort(scans.begin(), scans.end(),
                   [](const DatasetScan& a, const DatasetScan& b) { return a.stamp_ns < b.stamp_ns; });
  return scans;
}

Sweep read_dataset_scan(const DatasetScan& scan) {
  Sweep s;
  s.points = read_kitti_bin(scan.bin);
  s.has_intensity = true;
  if (!scan.meta.empty()) {
    read_point_meta(scan.meta, s.points);
    s.has_time = true;
    s.has_ring = true;
  }
  return s;
}

DatasetWriter::DatasetWriter(fs::path dir, bool overwrite) : dir_(std::move(dir)), overwrite_(overwrite) {
  if (fs::exists(dir_) && !overwrite_) {
    throw std::runtime_error(dir_.string() + ": exists (choose another folder or overwrite it)");
  }
  partial_ = dir_;
  partial_ += ".partial";
  fs::remove_all(partial_);
  fs::create_directories(partial_);
}

DatasetWriter::~DatasetWriter() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(partial_, ec);
  }
}

fs::path DatasetWriter::robot_dir(uint32_t robot) const { return partial_ / ("robot_" + std::to_string(robot)); }

size_t DatasetWriter::sweeps(uint32_t robot) const {
  const auto it = stamps_.find(robot);
  return it == stamps_.end() ? 0 : it->second.size();
}

void DatasetWriter::add_sweep(uint32_t robot, int64_t stamp_ns, const Sweep& sweep) {
  if (stamp_ns < 0)
    throw std::runtime_error("robot " + std::to_string(robot) + ": negative sweep time " + std::to_string(stamp_ns) +
                             " ns");
  std::vector<int64_t>& stamps = stamps_[robot];
  if (!stamps.empty() && stamp_ns <= stamps.back()) {
    throw std::runtime_error("robot " + std::to_string(robot) + ": sweep at " + std::to_string(stamp_ns) +
                             " ns does not follow the previous one at " + std::to_string(stamps.back()) + " ns");
  }
  const fs::path rd = robot_dir(robot);
  const std::string name = sweep_name(stamps.size());
  if (stamps.empty()) fs::create_directories(rd / "velodyne");
  write_kitti_bin(rd / "velodyne" / name, sweep.points);
  if (sweep.has_time || sweep.has_ring) {
    if (!stamps.empty() && !fs::is_directory(rd / "velodyne_meta")) {
      throw std::runtime_error("robot " + std::to_string(robot) + ": sweep " + std::to_string(stamps.size()) +
                               " has per-point times but the earlier sweeps had none");
    }
    fs::create_directories(rd / "velodyne_meta");
    write_point_meta(rd / "velodyne_meta" / name, sweep.points);
  } else if (fs::is_directory(rd / "velodyne_meta")) {
    throw std::runtime_error("robot " + std::to_string(robot) + ": sweep " + std::to_string(stamps.size()) +
                             " has no per-point times but the earlier sweeps had them");
  }
  stamps.push_back(stamp_ns);
  points_ += sweep.points.size();
}

void DatasetWriter::set_groundtruth(uint32_t robot, const geometry::Trajectory& poses) {
  fs::create_directories(robot_dir(robot));
  geometry::write_tum((robot_dir(robot) / "groundtruth.tum").string(), poses);
}

void DatasetWriter::set_imu(uint32_t robot, const std::vector<DatasetImu>& imu) {
  fs::create_directories(robot_dir(robot));
  std::string csv = "t,ax,ay,az,gx,gy,gz\n";
  for (const DatasetImu& m : imu) {
    char line[256];
    std::snprintf(line, sizeof line, "%.9f,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", static_cast<double>(m.stamp_ns) * 1e-9,
                  m.accel.x(), m.accel.y(), m.accel.z(), m.gyro.x(), m.gyro.y(), m.gyro.z());
    csv += line;
  }
  write_text(robot_dir(robot) / "imu.csv", csv);
}

void DatasetWriter::set_calib(uint32_t robot, const Eigen::Isometry3d& T_lidar_imu, const std::string& lidar_name,
                              double imu_rate_hz) {
  fs::create_directories(robot_dir(robot));
  const Eigen::Quaterniond q(T_lidar_imu.rotation());
  char calib[512];
  std::snprintf(calib, sizeof calib,
                "# T_lidar_imu: the IMU's pose in the LiDAR frame (position [m], quaternion x y z w)\n"
                "lidar: %s\nimu_rate_hz: %g\nT_lidar_imu: {position: [%g, %g, %g], orientation: [%g, %g, %g, %g]}\n",
                lidar_name.c_str(), imu_rate_hz, T_lidar_imu.translation().x(), T_lidar_imu.translation().y(),
                T_lidar_imu.translation().z(), q.x(), q.y(), q.z(), q.w());
  write_text(robot_dir(robot) / "calib.yaml", calib);
}

void DatasetWriter::set_radio(const std::string& radio_csv, const std::string& periods_csv) {
  write_text(partial_ / "radio.csv", radio_csv);
  write_text(partial_ / "radio_periods.csv", periods_csv);
}

DatasetInfo DatasetWriter::commit(DatasetInfo info) {
  if (stamps_.empty()) throw std::runtime_error(dir_.string() + ": no sweeps to write");
  uint32_t expected = 0;
  info.scans = 0;
  for (const auto& [robot, stamps] : stamps_) {
    if (robot != expected++)
      throw std::runtime_error(dir_.string() + ": robot " + std::to_string(expected - 1) + " has no sweeps");
    std::string times;
    for (const int64_t t : stamps) {
      char line[40];
      std::snprintf(line, sizeof line, "%lld.%09lld\n", static_cast<long long>(t / 1'000'000'000),
                    static_cast<long long>(t % 1'000'000'000));
      times += line;
    }
    write_text(robot_dir(robot) / "times.txt", times);
    info.scans += stamps.size();
  }
  info.robots = stamps_.size();
  info.points = points_;
  write_dataset_info(partial_, info);
  if (fs::exists(dir_)) fs::remove_all(dir_);
  fs::rename(partial_, dir_);
  committed_ = true;
  return info;
}

}  // namespace cdc::io
