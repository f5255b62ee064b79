#include "cdc/io/kitti.hpp"

#include "cdc/io/error.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace cdc::io {

Eigen::Isometry3d read_kitti_calib(const std::string& path, const std::string& key) {
  std::ifstream in(path);
  if (!in) {
    throw std::runtime_error(path + ": cannot open calibration file");
  }
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    std::istringstream s(line);
    std::string k;
    if (!(s >> k) || (k != key && k != key + ":")) {
      continue;
    }
    double v[12];
    for (double& x : v) {
      if (!(s >> x)) {
        throw std::runtime_error(path + ":" + std::to_string(n) + ": " + key + " needs 12 numbers");
      }
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
    T.translation() = Eigen::Vector3d(v[3], v[7], v[11]);
    return T;
  }
  throw std::runtime_error(path + ": no entry '" + key + "'");
}

namespace {

// Camera-frame poses T_world_cam0 into the LiDAR's: inv(Tr) * T * Tr.
void camera_to_lidar(geometry::Trajectory& poses, const Eigen::Isometry3d& Tr) {
  const Eigen::Isometry3d Tr_inv = Tr.inverse();
  for (auto& sp : poses) {
    sp.pose = Tr_inv * sp.pose * Tr;
  }
}

}  // namespace

geometry::Trajectory kitti_lidar_trajectory(const std::string& poses_path, const Eigen::Isometry3d& Tr) {
  geometry::Trajectory cam = geometry::read_kitti(poses_path, nullptr, 100'000'000);
  camera_to_lidar(cam, Tr);
  return cam;
}

std::vector<IndexRange> split_ranges(size_t count, const SplitOptions& o) {
  if (o.robots < 1 || o.overlap < 0 || o.overlap >= 1) {
    throw std::invalid_argument("split: robots must be >= 1 and overlap in [0, 1)");
  }
  const double n = static_cast<double>(count);
  const double piece = n / (o.robots - (o.robots - 1) * o.overlap);  // pieces tile the sequence
  std::vector<IndexRange> out;
  for (int k = 0; k < o.robots; ++k) {
    const size_t first = static_cast<size_t>(std::floor(k * piece * (1 - o.overlap)));
    const size_t last = std::min(count, static_cast<size_t>(std::ceil(static_cast<double>(first) + piece)));
    if (last <= first + 3) {
      throw std::invalid_argument("split: pieces too short for " + std::to_string(o.robots) + " robots");
    }
    out.push_back({first, last});
  }
  return out;
}

namespace {

// The piece driven from its end to its start on the opposite lane: poses in reverse order, each
// turned by pi about its own z and moved lane_m along its own (forward) y, stamps as they were.
geometry::Trajectory driven_in_reverse(const geometry::Trajectory& t, double lane_m) {
  geometry::Trajectory out;
  const Eigen::Isometry3d turn(Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitZ()));
  for (size_t i = 0; i < t.size(); ++i) {
    Eigen::Isometry3d T = t[t.size() - 1 - i].pose;
    T.translation() += T.linear() * Eigen::Vector3d(0, lane_m, 0);
    out.push_back({t[i].stamp_ns, T * turn});
  }
  return out;
}

}  // namespace

std::vector<geometry::Trajectory> split_robots(const geometry::Trajectory& seq, const SplitOptions& o) {
  for (int r : o.reverse) {
    if (r < 0 || r >= o.robots) {
      throw std::invalid_argument("split: reversed robot " + std::to_string(r) + " is not one of the " +
                                  std::to_string(o.robots) + " robots");
    }
  }
  std::vector<geometry::Trajectory> out;
  int k = 0;
  for (const IndexRange& r : split_ranges(seq.size(), o)) {
    geometry::Trajectory t(seq.begin() + static_cast<std::ptrdiff_t>(r.first),
                           seq.begin() + static_cast<std::ptrdiff_t>(r.last));
    const int64_t base = t.front().stamp_ns;
    const int64_t shift = static_cast<int64_t>(std::llround(k * o.time_shift_s * 1e9));
    for (auto& sp : t) {
      sp.stamp_ns = sp.stamp_ns - base + shift;
    }
    const bool reversed = std::find(o.reverse.begin(), o.reverse.end(), k) != o.reverse.end();
    out.push_back(reversed ? driven_in_reverse(t, o.reverse_lane_m) : std::move(t));
    ++k;
  }
  return out;
}

namespace {

namespace fs = std::filesystem;

bool is_frame_number(const std::string& stem) {
  return !stem.empty() && std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// The sweeps of the folder in frame order (a missing frame number is an error unless gaps are allowed).
void list_sweeps(const fs::path& dir, const KittiSequenceOptions& o, KittiSequence& seq) {
  // A sequence folder (velodyne/, times.txt, calib.txt) or a bare folder of .bin sweeps.
  const fs::path sweeps_dir = fs::is_directory(dir / "velodyne") ? dir / "velodyne" : dir;
  if (!fs::is_directory(sweeps_dir)) throw FormatError(dir.string() + ": not a folder");
  std::vector<std::pair<size_t, fs::path>> files;
  for (const auto& e : fs::directory_iterator(sweeps_dir)) {
    if (e.path().extension() != ".bin") continue;
    const std::string stem = e.path().stem().string();
    if (!is_frame_number(stem)) {
      throw FormatError(e.path().string() + ": a KITTI sweep is named by its frame number (NNNNNN.bin)");
    }
    files.emplace_back(static_cast<size_t>(std::stoull(stem)), e.path());
  }
  if (files.empty()) throw FormatError(sweeps_dir.string() + ": no .bin sweeps");
  std::sort(files.begin(), files.end());
  seq.first_frame = files.front().first;
  for (size_t i = 0; i < files.size(); ++i) {
    if (files[i].first != seq.first_frame + i && !o.allow_gaps) {
      char name[32];
      std::snprintf(name, sizeof name, "%06zu.bin", seq.first_frame + i);
      throw FormatError((sweeps_dir / name).string() + ": missing (frames " + std::to_string(seq.first_frame) + ".." +
                        std::to_string(files.back().first) + " have " + std::to_string(files.size()) + " files)");
    }
    seq.frames.push_back(files[i].first);
    seq.sweeps.push_back(files[i].second);
  }
}

// Times: an explicit file, else times.txt of the sequence, else frame * period; they must increase.
void stamp_frames(const fs::path& dir, const KittiSequenceOptions& o, KittiSequence& seq) {
  fs::path times_path = o.times;
  if (times_path.empty() && fs::exists(dir / "times.txt")) times_path = dir / "times.txt";
  std::vector<int64_t> all_times;
  if (!times_path.empty()) {
    all_times = geometry::read_times(times_path.string());
    seq.times_from_file = true;
  }
  for (const size_t f : seq.frames) {
    if (!all_times.empty()) {
      if (f >= all_times.size()) {
        throw FormatError(times_path.string() + ": " + std::to_string(all_times.size()) + " lines, no time for frame " +
                          std::to_string(f));
      }
      seq.stamps_ns.push_back(all_times[f]);
    } else {
      seq.stamps_ns.push_back(static_cast<int64_t>(f) * o.period_ns);
    }
  }
  for (size_t i = 1; i < seq.stamps_ns.size(); ++i) {
    if (seq.stamps_ns[i] <= seq.stamps_ns[i - 1]) {
      throw FormatError(times_path.string() + ": time of frame " + std::to_string(seq.frames[i]) +
                        " does not increase");
    }
  }
}

// Poses: camera-frame ground truth turned into the LiDAR frame with Tr, or LiDAR-frame poses as they are.
void attach_poses(const fs::path& dir, const KittiSequenceOptions& o, KittiSequence& seq) {
  geometry::Trajectory all = geometry::read_kitti(o.poses.string(), nullptr, o.period_ns);
  if (o.poses_frame == KittiPosesFrame::kCamera) {
    fs::path calib = o.calib;
    if (calib.empty() && fs::exists(dir / "calib.txt")) calib = dir / "calib.txt";
    if (calib.empty()) {
      throw FormatError(o.poses.string() + ": camera-frame poses need the calibration (calib.txt with Tr)");
    }
    camera_to_lidar(all, read_kitti_calib(calib.string(), o.calib_key));
  }
  for (size_t i = 0; i < seq.frames.size(); ++i) {
    if (seq.frames[i] >= all.size()) {
      throw FormatError(o.poses.string() + ": " + std::to_string(all.size()) + " poses, none for frame " +
                        std::to_string(seq.frames[i]));
    }
    seq.poses.push_back({seq.stamps_ns[i], all[seq.frames[i]].pose});
  }
}

}  // namespace

KittiSequence read_kitti_sequence(const std::filesystem::path& dir, const KittiSequenceOptions& o) {
  KittiSequence seq;
  list_sweeps(dir, o, seq);
  stamp_frames(dir, o, seq);
  if (!o.poses.empty()) {
    attach_poses(dir, o, seq);
  }
  return seq;
}

}  // namespace cdc::io
