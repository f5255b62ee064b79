#include "player.hpp"

#include "cdc/io/dataset.hpp"

#include "cdc/dds/convert.hpp"
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <thread>

namespace cdc::sim {
namespace fs = std::filesystem;

namespace {

using ScanRef = io::DatasetScan;
using io::DatasetImu;
using io::list_dataset_scans;

// Publishes a merged, time-ordered list of scans (and IMU per robot) with the chosen pacing.
class Publisher {
 public:
  explicit Publisher(const PlayOptions& o)
      : o_(o),
        participant_(make_options(o)),
        w_lidar_(participant_, dds::topics::kLidar, dds::qos::sensor_stream(16, true)),
        w_imu_(participant_, dds::topics::kImu, dds::qos::sensor_stream(64, true)),
        w_gt_(participant_, dds::topics::kGroundTruth, ground_truth_qos()),
        t_progress_(participant_, dds::topics::kProgress),
        r_progress_(participant_, t_progress_, dds::qos::keyed_state()),
        w_radio_(participant_, dds::topics::kRadio, dds::qos::keyed_state()) {
    if (o.wait_readers > 0 && !w_lidar_.wait_for_readers(o.wait_readers, std::chrono::seconds(30))) {
      throw std::runtime_error("only " + std::to_string(w_lidar_.matched_readers()) + " of " +
                               std::to_string(o.wait_readers) + " LiDAR readers appeared");
    }
    // Consumers read the IMU too: the first batch, written before its reader has matched, would be
    // lost (and the first sweep processed without it). Consumers without an IMU reader do not block
    // this for long.
    if (o.wait_readers > 0) w_imu_.wait_for_readers(o.wait_readers, std::chrono::seconds(3));
  }

  // Ground truth is a stream every sample of which matters (evaluation): reliable, deep, and
  // transient-local so that a reader that matches late still gets it.
  static dds::Qos ground_truth_qos() {
    dds::Qos q;
    q.reliable().keep_last(4096).transient_local();
    return q;
  }

  static dds::ParticipantOptions make_options(const PlayOptions& o) {
    dds::ParticipantOptions p;
    p.domain_id = o.domain;
    p.config = o.dds_config;
    return p;
  }

  void publish_imu(uint32_t robot, const std::vector<cdc_msg_ImuSample>& samples) {
    if (samples.empty()) return;
    std::vector<cdc_msg_ImuSample> copy = samples;
    cdc_msg_ImuBatch b{};
    b.robot_id = robot;
    b.incarnation = o_.incarnation;
    b.seq = imu_seq_[robot]++;
    b.sample_count = static_cast<uint32_t>(copy.size());
    dds::borrow(b.samples, copy);
    w_imu_.write(b);
  }

  void wait_consumed(uint32_t robot, uint64_t seq) {
    if (!o_.lockstep || seq == 0) return;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(o_.lockstep_timeout_s);
    while (true) {
      r_progress_.take(64).for_each_valid([&](const cdc_msg_ConsumerProgress& p, const dds_sample_info_t&) {
        consumed_[p.robot_id] = std::max(consumed_[p.robot_id], static_cast<int64_t>(p.last_scan_seq));
      });
      auto it = consumed_.find(robot);
      if (it != consumed_.end() && it->second >= static_cast<int64_t>(seq) - 1) return;
      if (dds::ShutdownSignal::requested()) throw std::runtime_error("stopped by signal");
      if (std::chrono::steady_clock::now() > deadline) {
        throw std::runtime_error("lock-step: robot " + std::to_string(robot) + "'s consumer did not report scan " +
                                 std::to_string(seq - 1) + " within " + std::to_string(o_.lockstep_timeout_s) + " s");
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }

  void publish_scan(const ScanRef& s) {
    const io::Sweep sweep = io::read_dataset_scan(s);
    const std::vector<io::CloudPoint>& in = sweep.points;
    const size_t n = in.size();
    std::vector<cdc_msg_LidarPoint> pts(n);
    for (size_t i = 0; i < n; ++i) {
      cdc_msg_LidarPoint& p = pts[i];
      p.x = in[i].x;
      p.y = in[i].y;
      p.z = in[i].z;
      p.intensity = in[i].intensity;
      p.time_offset = in[i].time_offset;
      p.ring = in[i].ring;
    }
    cdc_msg_LidarScan m{};
    m.robot_id = s.robot;
    m.incarnation = o_.incarnation;
    m.seq = s.seq;
    m.stamp_ns = s.stamp_ns;
    m.duration_ns = sweep.has_time ? o_.sweep_duration_ns : 0;  // 0: motion-compensated, no per-point times
    m.point_count = static_cast<uint32_t>(n);
    dds::borrow(m.points, pts);
    w_lidar_.write(m);
    if (s.truth) {
      cdc_msg_GroundTruth g{};
      g.robot_id = s.robot;
      g.stamp_ns = s.stamp_ns;
      g.T_world_base = dds::to_msg(*s.truth);
      w_gt_.write(g);
    }
  }

  // Paces by data time (rate > 0) from the first scan.
  void pace(int64_t stamp_ns) {
    if (o_.rate <= 0 || o_.lockstep) return;
    if (!start_) {
      start_ = std::chrono::steady_clock::now();
      first_stamp_ = stamp_ns;
    }
    const auto due = *start_ + std::chrono::nanoseconds(
                                   static_cast<int64_t>(static_cast<double>(stamp_ns - first_stamp_) / o_.rate));
    std::this_thread::sleep_until(due);
  }

 private:
  PlayOptions o_;
  dds::Participant participant_;
  dds::TopicWriter<cdc_msg_LidarScan> w_lidar_;
  dds::TopicWriter<cdc_msg_ImuBatch> w_imu_;
  dds::TopicWriter<cdc_msg_GroundTruth> w_gt_;
  dds::Topic<cdc_msg_ConsumerProgress> t_progress_;
  dds::Reader<cdc_msg_ConsumerProgress> r_progress_;

 public:
  // Publishes the radio links of one timeline instant.
  void publish_radio(int64_t stamp_ns, std::vector<cdc_msg_RadioLink>& links) {
    cdc_msg_RadioState m{};
    m.scenario_id = 0;
    m.stamp_ns = stamp_ns;
    dds::borrow(m.links, links);
    w_radio_.write(m);
  }

 private:
  dds::TopicWriter<cdc_msg_RadioState> w_radio_;
  std::map<uint32_t, uint64_t> imu_seq_;
  std::map<uint32_t, int64_t> consumed_;
  std::optional<std::chrono::steady_clock::time_point> start_;
  int64_t first_stamp_ = 0;
};

std::vector<cdc_msg_ImuSample> read_imu(const fs::path& p) {
  std::vector<cdc_msg_ImuSample> out;
  for (const DatasetImu& m : io::read_dataset_imu(p))
    out.push_back(cdc_msg_ImuSample{m.stamp_ns, dds::to_msg(m.accel), dds::to_msg(m.gyro)});
  return out;
}

// radio.csv -> instants with their links, in time order.
std::vector<std::pair<int64_t, std::vector<cdc_msg_RadioLink>>> read_radio(const fs::path& p) {
  std::vector<std::pair<int64_t, std::vector<cdc_msg_RadioLink>>> out;
  std::ifstream in(p);
  if (!in) {
    return out;  // optional
  }
  std::string line;
  size_t n = 1;
  std::getline(in, line);
  while (std::getline(in, line)) {
    ++n;
    double t, dist, loss;
    unsigned a, b;
    int in_range;
    if (std::sscanf(line.c_str(), "%lf,%u,%u,%d,%lf,%lf", &t, &a, &b, &in_range, &dist, &loss) != 6) {
      throw std::runtime_error(p.string() + ":" + std::to_string(n) + ": expected t,a,b,in_range,distance,loss");
    }
    const int64_t ns = static_cast<int64_t>(std::llround(t * 1e9));
    if (out.empty() || out.back().first != ns) {
      out.push_back({ns, {}});
    }
    out.back().second.push_back(
        cdc_msg_RadioLink{a, b, in_range != 0, static_cast<float>(dist), static_cast<float>(loss)});
  }
  return out;
}

// Replaces the clock file atomically so that a reader never sees half a line.
void write_clock(const std::string& path, int64_t stamp_ns, size_t scans) {
  if (path.empty()) return;
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) throw std::runtime_error(path + ": cannot write the clock file");
    out << stamp_ns << ' ' << scans << '\n';
  }
  fs::rename(tmp, path);
}

}  // namespace

PlaySummary play_dataset(const std::string& dir, const PlayOptions& o) {
  if (!fs::is_directory(dir)) {
    throw std::runtime_error(dir + ": not a dataset folder");
  }
  const io::DatasetInfo info = io::read_dataset_info(dir);
  PlayOptions options = o;
  options.sweep_duration_ns = static_cast<int64_t>(std::llround(info.sweep_period_s * 1e9));
  std::vector<ScanRef> scans = list_dataset_scans(dir, o.max_scans);
  if (o.only_robot >= 0) {
    scans.erase(std::remove_if(scans.begin(), scans.end(),
                               [&](const ScanRef& s) { return s.robot != static_cast<uint32_t>(o.only_robot); }),
                scans.end());
    if (scans.empty()) throw std::runtime_error(dir + ": no scans of robot " + std::to_string(o.only_robot));
  }
  std::map<uint32_t, std::vector<cdc_msg_ImuSample>> imu;
  for (const ScanRef& s : scans) {
    if (imu.count(s.robot) == 0)
      imu[s.robot] = read_imu(fs::path(dir) / ("robot_" + std::to_string(s.robot)) / "imu.csv");
  }
  auto radio = read_radio(fs::path(dir) / "radio.csv");
  size_t radio_next = 0;
  Publisher pub(options);
  std::map<uint32_t, size_t> imu_next;
  PlaySummary sum;
  for (const ScanRef& s : scans) {
    if (dds::ShutdownSignal::requested()) break;
    pub.wait_consumed(s.robot, s.seq);
    pub.pace(s.stamp_ns);
    // IMU up to this scan's end, then the scan.
    auto& samples = imu[s.robot];
    size_t& next = imu_next[s.robot];
    std::vector<cdc_msg_ImuSample> batch;
    while (next < samples.size() && samples[next].stamp_ns <= s.stamp_ns + 100'000'000) {
      batch.push_back(samples[next++]);
    }
    pub.publish_imu(s.robot, batch);
    sum.imu_samples += batch.size();
    while (radio_next < radio.size() && radio[radio_next].first <= s.stamp_ns) {
      pub.publish_radio(radio[radio_next].first, radio[radio_next].second);
      ++radio_next;
      ++sum.radio_states;
    }
    pub.publish_scan(s);
    ++sum.scans;
    write_clock(o.clock_file, s.stamp_ns, sum.scans);
  }
  return sum;
}

}  // namespace cdc::sim
