#include "import.hpp"

#include "cdc/io/bag.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/ros_messages.hpp"
#include "cdc/io/velodyne.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>

namespace cdc::sim {
namespace fs = std::filesystem;
namespace {

// Position of a robot at time t [s]: its poses interpolated, held at the first and last pose outside.
Eigen::Vector3d position_at(const geometry::Trajectory& poses, double t) {
  const auto ns = static_cast<int64_t>(std::llround(t * 1e9));
  if (ns <= poses.front().stamp_ns) return poses.front().pose.translation();
  if (ns >= poses.back().stamp_ns) return poses.back().pose.translation();
  return geometry::interpolate_at(poses, ns).value_or(poses.back().pose).translation();
}

std::string periods_csv(const std::vector<OutOfRangePeriod>& periods) {
  std::string out = "a,b,start,end\n";
  for (const auto& p : periods) {
    char line[96];
    std::snprintf(line, sizeof line, "%u,%u,%.3f,%.3f\n", p.a, p.b, p.start, p.end);
    out += line;
  }
  return out;
}

// Out-of-range periods from a user's timeline file (a,b,start,end per line, header optional).
std::vector<OutOfRangePeriod> read_periods(const fs::path& p, const std::set<uint32_t>& nodes) {
  std::ifstream in(p);
  if (!in) throw io::FormatError(p.string() + ": cannot open the radio timeline");
  std::vector<OutOfRangePeriod> out;
  std::string line;
  size_t n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (line.empty() || line[0] == '#' || line.rfind("a,", 0) == 0) continue;
    OutOfRangePeriod o;
    if (std::sscanf(line.c_str(), "%u,%u,%lf,%lf", &o.a, &o.b, &o.start, &o.end) != 4) {
      throw io::FormatError(p.string() + ":" + std::to_string(n) + ": expected a,b,start,end (node ids, seconds)");
    }
    if (nodes.count(o.a) == 0 || nodes.count(o.b) == 0 || o.a == o.b) {
      throw io::FormatError(p.string() + ":" + std::to_string(n) + ": nodes " + std::to_string(o.a) + "," +
                            std::to_string(o.b) + " are not two of this run's robots or its central");
    }
    if (!(o.end > o.start)) throw io::FormatError(p.string() + ":" + std::to_string(n) + ": end must be after start");
    if (o.a > o.b) std::swap(o.a, o.b);
    out.push_back(o);
  }
  return out;
}

// A temporary folder removed with the last Recording that holds it.
struct ScratchDir {
  fs::path path;
  explicit ScratchDir(fs::path p) : path(std::move(p)) {
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
};

// The one topic of `type`, or the named one (which must have that type or `other_type`).
std::string pick_topic(const std::vector<io::BagTopic>& topics, const std::string& wanted,
                       const std::vector<std::string>& types, const std::string& what, const std::string& bag) {
  if (!wanted.empty()) {
    for (const auto& t : topics) {
      if (t.name != wanted) continue;
      if (std::find(types.begin(), types.end(), t.type) == types.end()) {
        throw io::FormatError(bag + ": topic " + wanted + " is " + t.type + ", not a " + what + " topic");
      }
      return t.name;
    }
    throw io::FormatError(bag + ": no topic " + wanted);
  }
  std::vector<std::string> found;
  for (const auto& t : topics) {
    if (std::find(types.begin(), types.end(), t.type) != types.end()) found.push_back(t.name);
  }
  if (found.size() > 1) {
    std::string list;
    for (const auto& f : found) list += " " + f;
    throw io::FormatError(bag + ": several " + what + " topics (" + list + " ); choose one");
  }
  return found.empty() ? std::string() : found.front();
}

// A driver that stamps a cloud at its end gives its points negative offsets: shift the times so that
// the earliest is 0 and return that shift [ns] (0 when no offset is negative).
int64_t normalise_times(io::Sweep& s) {
  if (!s.has_time || s.points.empty()) return 0;
  float lo = 0;
  for (const auto& p : s.points) lo = std::min(lo, p.time_offset);
  if (lo == 0) return 0;
  for (auto& p : s.points) p.time_offset -= lo;
  return static_cast<int64_t>(std::llround(static_cast<double>(lo) * 1e9));
}

}  // namespace

io::Sweep Recording::sweep(size_t i) const {
  io::Sweep s = io::read_cloud_file(files.at(i));
  if (i < meta_files.size() && !meta_files[i].empty()) {
    io::read_point_meta(meta_files[i], s.points);
    s.has_time = s.has_ring = true;
  }
  return s;
}

void times_from_azimuth(io::Sweep& sweep, double period_s) {
  for (io::CloudPoint& p : sweep.points) {
    const double az = std::atan2(static_cast<double>(p.y), static_cast<double>(p.x));
    p.time_offset = static_cast<float>(period_s * (az + M_PI) / (2 * M_PI));
  }
  sweep.has_time = true;
}

Recording kitti_recording(const fs::path& dir, const io::KittiSequenceOptions& options, io::PointTimes point_times,
                          const std::string& poses_kind) {
  if (point_times == io::PointTimes::kSensor) throw std::invalid_argument("KITTI sweeps carry no per-point times");
  const io::KittiSequence seq = io::read_kitti_sequence(dir, options);
  Recording r;
  r.source = "kitti";
  r.stamps_ns = seq.stamps_ns;
  r.files = seq.sweeps;
  r.poses = seq.poses;
  r.poses_kind = seq.poses.empty() ? "none" : poses_kind;
  r.point_times = point_times;
  r.sweep_period_s = static_cast<double>(options.period_ns) * 1e-9;
  if (seq.stamps_ns.size() > 1) {
    r.sweep_period_s = static_cast<double>(seq.stamps_ns.back() - seq.stamps_ns.front()) * 1e-9 /
                       static_cast<double>(seq.stamps_ns.size() - 1);
  }
  r.notes.push_back(std::to_string(seq.sweeps.size()) + " sweeps, frames " + std::to_string(seq.frames.front()) + ".." +
                    std::to_string(seq.frames.back()) +
                    (seq.times_from_file ? ", times from the times file" : ", times from the period"));
  return r;
}

void attach_poses(Recording& r, const fs::path& poses, const std::string& kind) {
  const geometry::TrajectoryFormat format = geometry::detect_format(poses.string());
  r.poses.clear();
  if (format == geometry::TrajectoryFormat::kKitti) {
    r.poses = geometry::read_kitti(poses.string(), &r.stamps_ns);
    if (r.poses.size() != r.size()) {
      throw io::FormatError(poses.string() + ": " + std::to_string(r.poses.size()) + " poses for " +
                            std::to_string(r.size()) + " sweeps");
    }
  } else {
    const geometry::Trajectory tum = geometry::read_tum(poses.string());
    for (const int64_t t : r.stamps_ns) {
      const auto p = geometry::interpolate_at(tum, t);
      if (!p)
        throw io::FormatError(poses.string() + ": no pose at the sweep time " +
                              std::to_string(static_cast<double>(t) * 1e-9) + " s");
      r.poses.push_back({t, *p});
    }
  }
  r.poses_kind = kind;
}

Recording sweep_folder_recording(const fs::path& dir, const SweepFolderOptions& o) {
  if (!fs::is_directory(dir)) throw io::FormatError(dir.string() + ": not a folder");
  std::vector<fs::path> files;
  std::set<std::string> exts;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.is_regular_file() && io::is_cloud_file(e.path())) {
      files.push_back(e.path());
      exts.insert(e.path().extension().string());
    }
  }
  if (files.empty()) throw io::FormatError(dir.string() + ": no .bin, .pcd or .ply sweeps");
  if (exts.size() > 1) throw io::FormatError(dir.string() + ": sweeps of several formats; keep one kind per folder");
  std::sort(files.begin(), files.end());
  // Numbered names (000012.pcd) must not skip a number: a missing sweep would shift every time and pose.
  bool numbered = true;
  for (const auto& f : files) {
    const std::string stem = f.stem().string();
    numbered =
        numbered && !stem.empty() && std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; });
  }
  if (numbered) {
    const auto first = std::stoull(files.front().stem().string());
    for (size_t i = 0; i < files.size(); ++i) {
      if (std::stoull(files[i].stem().string()) != first + i) {
        throw io::FormatError(dir.string() + ": sweep number " + std::to_string(first + i) + " is missing (found " +
                              files[i].filename().string() + " next)");
      }
    }
  }
  Recording r;
  r.source = "sweeps";
  r.files = files;
  r.sweep_period_s = o.period_s;
  fs::path times = o.times;
  if (times.empty() && fs::exists(dir / "times.txt")) times = dir / "times.txt";
  if (!times.empty()) {
    const std::vector<int64_t> t = geometry::read_times(times.string());
    if (t.size() != files.size()) {
      throw io::FormatError(times.string() + ": " + std::to_string(t.size()) + " times for " +
                            std::to_string(files.size()) + " sweeps");
    }
    r.stamps_ns = t;
    for (size_t i = 1; i < t.size(); ++i) {
      if (t[i] <= t[i - 1])
        throw io::FormatError(times.string() + ":" + std::to_string(i + 1) + ": time does not increase");
    }
    if (t.size() > 1)
      r.sweep_period_s = static_cast<double>(t.back() - t.front()) * 1e-9 / static_cast<double>(t.size() - 1);
    r.notes.push_back("times from " + times.string());
  } else {
    for (size_t i = 0; i < files.size(); ++i)
      r.stamps_ns.push_back(static_cast<int64_t>(std::llround(static_cast<double>(i) * o.period_s * 1e9)));
    r.notes.push_back("times from the period (" + std::to_string(o.period_s) + " s)");
  }
  if (!o.poses.empty()) attach_poses(r, o.poses, o.poses_kind);
  // The first sweep tells which fields the folder's sweeps have.
  const io::Sweep first = io::read_cloud_file(files.front());
  r.point_times = first.has_time ? io::PointTimes::kSensor : io::PointTimes::kNone;
  r.notes.push_back(first.has_time ? "sweeps carry per-point times"
                                   : "sweeps carry no per-point times: taken as motion-compensated");
  return r;
}

Recording bag_recording(const fs::path& bag_path, const BagImportOptions& o, const fs::path& scratch_dir) {
  const std::unique_ptr<io::BagReader> bag = io::open_bag(bag_path);
  const std::string name = bag_path.string();
  const std::vector<io::BagTopic> topics = bag->topics();
  const std::string kCloud(io::kPointCloud2Type), kScan(io::kVelodyneScanType), kImu(io::kImuType);
  const std::string lidar =
      pick_topic(topics, o.lidar_topic, {kCloud, kScan}, "LiDAR (PointCloud2 or VelodyneScan)", name);
  if (lidar.empty()) throw io::FormatError(name + ": no PointCloud2 or VelodyneScan topic");
  const std::string imu = o.imu_topic == "none" ? std::string() : pick_topic(topics, o.imu_topic, {kImu}, "Imu", name);
  std::string lidar_type;
  for (const auto& t : topics) {
    if (t.name == lidar) lidar_type = t.type;
  }

  Recording r;
  r.source = bag->describe().rfind("ROS 1", 0) == 0 ? "rosbag1" : "rosbag2";
  auto scratch = std::make_shared<ScratchDir>(scratch_dir);
  r.scratch = scratch;
  r.T_lidar_imu = o.T_lidar_imu;
  std::map<std::string, size_t> reasons, first_seen;  // why messages were skipped: how often, first message index
  size_t extracted = 0;
  bool any_time = false, any_without_time = false;
  const auto store = [&](int64_t stamp_ns, io::Sweep& s) {
    if (!r.stamps_ns.empty() && stamp_ns <= r.stamps_ns.back()) {
      ++r.skipped;
      ++reasons["sweep stamp not after the previous sweep's"];
      return;
    }
    char file[32];
    std::snprintf(file, sizeof file, "%06zu.bin", extracted++);
    io::write_kitti_bin(scratch->path / file, s.points);
    r.files.push_back(scratch->path / file);
    if (s.has_time) {
      const fs::path meta = scratch->path / (std::string(file) + ".meta");
      io::write_point_meta(meta, s.points);
      r.meta_files.push_back(meta);
      any_time = true;
    } else {
      r.meta_files.emplace_back();
      any_without_time = true;
    }
    r.stamps_ns.push_back(stamp_ns);
  };

  std::optional<io::VelodyneSweepAssembler> assembler;
  if (lidar_type == kScan) {
    io::VelodyneDecoderOptions d;
    if (!o.velodyne_model.empty()) d.model = io::velodyne_model_from_string(o.velodyne_model);
    d.min_range = o.min_range_m;
    d.max_range = o.max_range_m;
    io::VelodyneCalibration calib;
    if (!o.velodyne_calibration.empty()) {
      calib = io::read_velodyne_calibration(o.velodyne_calibration, d.model);
    } else if (d.model) {
      calib = io::default_velodyne_calibration(*d.model);
      r.notes.push_back("Velodyne: the built-in " + std::string(io::to_string(*d.model)) +
                        " table (give the unit's --calibration)");
    } else {
      throw std::invalid_argument(name + ": VelodyneScan packets need the sensor's --calibration or its --model");
    }
    assembler.emplace(calib, d, io::VelodyneSweepOptions::whole_turns(o.velodyne_scan_phase_deg));
  }
  const auto drain = [&] {
    while (assembler && assembler->has_sweep()) {
      const io::VelodyneSweep v = assembler->take();
      if (v.points.empty()) {
        ++r.skipped;
        ++reasons["Velodyne sweep without points in range"];
        continue;
      }
      int64_t stamp = 0;
      io::Sweep s = io::to_sweep(v, stamp);
      store(stamp, s);
    }
  };

  io::BagMessage m;
  size_t index = 0;
  while (bag->next(m)) {
    ++index;
    try {
      if (m.topic == lidar && lidar_type == kCloud) {
        const io::PointCloud2Msg c = io::decode_point_cloud2(m);
        io::DecodedCloud d = io::cloud_points(c);
        if (d.points.empty()) throw io::FormatError("no finite points");
        io::Sweep& s = d;
        const int64_t first = normalise_times(s);
        store(c.header.stamp_ns + first, s);
      } else if (m.topic == lidar) {
        for (const io::VelodynePacketMsg& p : io::decode_velodyne_scan(m).packets) {
          assembler->add_packet(p.data, p.stamp_ns);
        }
        drain();
      } else if (!imu.empty() && m.topic == imu) {
        const io::ImuMsg i = io::decode_imu(m);
        if (!r.imu.empty() && i.header.stamp_ns <= r.imu.back().stamp_ns) {
          ++r.skipped;
          ++reasons["IMU stamp not after the previous sample's"];
          continue;
        }
        r.imu.push_back({i.header.stamp_ns, i.linear_acceleration, i.angular_velocity});
      }
    } catch (const io::FormatError& e) {
      ++r.skipped;
      if (reasons[e.what()]++ == 0) first_seen[e.what()] = index;
    }
  }
  if (assembler) {
    const io::VelodyneSweepStats& st = assembler->stats();
    r.notes.push_back("Velodyne: " + std::to_string(st.packets) + " packets, " + std::to_string(st.sweeps) +
                      " sweeps, " + std::to_string(st.truncated + st.malformed) + " bad and " +
                      std::to_string(st.out_of_order) + " out-of-order packets skipped");
    r.skipped += st.truncated + st.malformed + st.out_of_order;
  }
  for (const auto& [why, n] : reasons) {
    const auto first = first_seen.find(why);
    r.notes.push_back("skipped " + std::to_string(n) + " x" +
                      (first != first_seen.end()
                           ? " (first: message " + std::to_string(first->second) + " of " + name + ")"
                           : std::string()) +
                      ": " + why);
  }
  if (r.stamps_ns.empty()) throw io::FormatError(name + ": no sweep could be read from " + lidar);
  if (any_time && any_without_time) {
    throw io::FormatError(name + ": some sweeps of " + lidar + " carry per-point times and others do not");
  }
  r.point_times = any_time ? io::PointTimes::kSensor : io::PointTimes::kNone;
  if (!any_time) r.meta_files.clear();
  r.notes.push_back(std::to_string(r.size()) + " sweeps from " + lidar +
                    (any_time ? " with per-point times" : ", no per-point times (taken as motion-compensated)"));
  if (r.size() > 1) {
    r.sweep_period_s =
        static_cast<double>(r.stamps_ns.back() - r.stamps_ns.front()) * 1e-9 / static_cast<double>(r.size() - 1);
  }
  if (!r.imu.empty()) {
    r.notes.push_back(std::to_string(r.imu.size()) + " IMU samples from " + imu +
                      (o.T_lidar_imu_given ? "" : "; T_lidar_imu not given: identity assumed"));
  }
  return r;
}

ImportSummary write_import(const Recording& rec, const ImportOptions& o) {
  if (rec.size() == 0) throw std::runtime_error("the recording holds no sweeps");
  if (o.robots < 1) throw std::invalid_argument("robots must be at least 1");
  if (!rec.poses.empty() && rec.poses.size() != rec.size()) throw std::logic_error("poses must be one per sweep");
  ImportSummary sum;
  sum.notes = rec.notes;
  sum.skipped = rec.skipped;
  std::vector<io::IndexRange> ranges;
  if (o.robots == 1) {
    ranges.push_back({0, rec.size()});
  } else {
    io::SplitOptions split;
    split.robots = o.robots;
    split.overlap = o.overlap;
    split.time_shift_s = o.time_shift_s;
    ranges = io::split_ranges(rec.size(), split);
  }
  io::DatasetWriter writer(o.out, o.overwrite);
  std::vector<geometry::Trajectory> robot_poses(ranges.size());
  double t0 = 1e300, t1 = -1e300;
  for (size_t k = 0; k < ranges.size(); ++k) {
    const uint32_t robot = static_cast<uint32_t>(k);
    size_t last = ranges[k].last;
    if (o.max_scans > 0) last = std::min(last, ranges[k].first + o.max_scans);
    // The IMU samples from kImuMargin before the robot's first sweep to kImuMargin after its last.
    const int64_t start = rec.stamps_ns[ranges[k].first];
    const int64_t end = rec.stamps_ns[last - 1] + static_cast<int64_t>(std::llround(rec.sweep_period_s * 1e9));
    constexpr int64_t kImuMargin = 500'000'000;
    std::vector<io::DatasetImu> imu;
    for (const io::DatasetImu& m : rec.imu) {
      if (m.stamp_ns >= start - kImuMargin && m.stamp_ns <= end + kImuMargin) imu.push_back(m);
    }
    // Robot k's clock: its first sample (sweep or IMU) at k * time_shift_s.
    const int64_t origin = imu.empty() ? start : std::min(start, imu.front().stamp_ns);
    const int64_t offset = static_cast<int64_t>(std::llround(static_cast<double>(k) * o.time_shift_s * 1e9)) - origin;
    for (size_t i = ranges[k].first; i < last; ++i) {
      io::Sweep s = rec.sweep(i);
      if (rec.point_times == io::PointTimes::kAzimuth) times_from_azimuth(s, rec.sweep_period_s);
      writer.add_sweep(robot, rec.stamps_ns[i] + offset, s);
      if (!rec.poses.empty()) robot_poses[k].push_back({rec.stamps_ns[i] + offset, rec.poses[i].pose});
    }
    if (!robot_poses[k].empty()) writer.set_groundtruth(robot, robot_poses[k]);
    if (!imu.empty()) {
      for (io::DatasetImu& m : imu) m.stamp_ns += offset;
      writer.set_imu(robot, imu);
      const double rate = imu.size() > 1 ? static_cast<double>(imu.size() - 1) /
                                               (static_cast<double>(imu.back().stamp_ns - imu.front().stamp_ns) * 1e-9)
                                         : 0.0;
      writer.set_calib(robot, rec.T_lidar_imu, rec.source, rate);
    }
    t0 = std::min(t0, static_cast<double>(start + offset) * 1e-9);
    t1 = std::max(t1, static_cast<double>(end + offset) * 1e-9);
  }

  // The radio.
  io::DatasetInfo info;
  info.name = o.name.empty() ? o.out.filename().string() : o.name;
  info.source = rec.source;
  info.point_times = rec.point_times;
  info.sweep_period_s = rec.sweep_period_s;
  info.poses = rec.poses_kind;
  info.central_id = o.radio.central_id;
  for (uint32_t r = 0; r < ranges.size(); ++r) {
    if (r == o.radio.central_id)
      throw std::invalid_argument("the central id " + std::to_string(r) + " collides with a robot id");
  }
  const RadioOptions& ro = o.radio.options;
  std::vector<LinkSample> timeline;
  std::vector<OutOfRangePeriod> periods;
  const bool with_central_range = o.radio.central_range_m > 0;
  if (!o.radio.timeline.empty()) {
    std::set<uint32_t> nodes{o.radio.central_id};
    for (uint32_t r = 0; r < ranges.size(); ++r) nodes.insert(r);
    periods = read_periods(o.radio.timeline, nodes);
    // Link states at every period step: out of range inside a listed period.
    const auto steps = static_cast<int64_t>(std::floor((t1 - t0) / ro.period_s + 1e-9));
    for (int64_t s = 0; s <= steps; ++s) {
      const double t = t0 + static_cast<double>(s) * ro.period_s;
      for (auto a = nodes.begin(); a != nodes.end(); ++a) {
        for (auto b = std::next(a); b != nodes.end(); ++b) {
          LinkSample l;
          l.t = t;
          l.a = *a;
          l.b = *b;
          l.in_range = std::none_of(periods.begin(), periods.end(), [&](const OutOfRangePeriod& p) {
            return p.a == *a && p.b == *b && t >= p.start && t < p.end;
          });
          l.loss = l.in_range ? 0.0 : 1.0;
          timeline.push_back(l);
        }
      }
    }
    periods = out_of_range_periods(timeline);
    info.radio = "timeline";
    sum.notes.push_back("radio from the timeline " + o.radio.timeline.string());
  } else if (!rec.poses.empty() && with_central_range) {
    if (o.radio.central_robot >= static_cast<int>(ranges.size())) {
      throw std::invalid_argument("the central rides on robot " + std::to_string(o.radio.central_robot) +
                                  ", but there are " + std::to_string(ranges.size()) + " robots");
    }
    std::vector<RadioNode> nodes;
    const double robot_range = o.radio.robot_range_m > 0 ? o.radio.robot_range_m : o.radio.central_range_m;
    for (size_t k = 0; k < ranges.size(); ++k) {
      const geometry::Trajectory* p = &robot_poses[k];
      nodes.push_back({static_cast<uint32_t>(k), robot_range, [p](double t) { return position_at(*p, t); }});
    }
    if (o.radio.central_robot >= 0) {
      const geometry::Trajectory* p = &robot_poses[static_cast<size_t>(o.radio.central_robot)];
      nodes.push_back({o.radio.central_id, o.radio.central_range_m, [p](double t) { return position_at(*p, t); }});
    } else {
      const Eigen::Vector3d c = o.radio.central_position;
      nodes.push_back({o.radio.central_id, o.radio.central_range_m, [c](double) { return c; }});
    }
    timeline = radio_timeline(nodes, t0, t1, ro);
    periods = out_of_range_periods(timeline);
    info.radio = "reference_poses";
    sum.notes.push_back("radio from the " + rec.poses_kind + " poses: central range " +
                        std::to_string(o.radio.central_range_m) + " m");
  } else {
    if (ranges.size() > 1 && !rec.poses.empty()) {
      throw std::invalid_argument(
          "several robots with poses: give the central's range (--central-range) or a radio timeline");
    }
    // No radio information: every link in range for the whole run.
    std::vector<RadioNode> nodes;
    for (size_t k = 0; k < ranges.size(); ++k)
      nodes.push_back({static_cast<uint32_t>(k), 1.0, [](double) { return Eigen::Vector3d::Zero(); }});
    nodes.push_back({o.radio.central_id, 1.0, [](double) { return Eigen::Vector3d::Zero(); }});
    timeline = radio_timeline(nodes, t0, t1, ro);
    info.radio = "none";
    sum.notes.push_back("no radio information: every link in range");
  }
  writer.set_radio(radio_csv(timeline), periods_csv(periods));
  info.out_of_range_periods = periods.size();
  sum.info = writer.commit(info);
  return sum;
}

}  // namespace cdc::sim
