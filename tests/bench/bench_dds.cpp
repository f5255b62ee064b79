// cdc-bench-dds: cost of moving one LiDAR sweep through the DDS layer within one process
// (Writer::write and Reader::take of cdc/sensor/lidar, per-topic byte counting included), of
// measuring its serialised size as the writer does (a walk over the type's instructions), and of
// serialising it once more instead (how both sides counted before). Medians over --rounds. Needs a Cyclone
// configuration (CYCLONEDDS_URI or
// --config); run it with deploy/cyclonedds/loopback.xml. Last output line: one JSON object.
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/traffic.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-bench-dds: write/take cost of one LiDAR sweep through the DDS layer (one process)"};
  size_t points = 28800;
  int rounds = 200;
  std::string config;
  app.add_option("--points", points, "points per sweep (28,800: a VLP-16 sweep of the simulator)")
      ->check(CLI::Range(size_t{1}, size_t{2000000}));
  app.add_option("--rounds", rounds, "sweeps written and taken")->check(CLI::Range(5, 100000));
  app.add_option("--config", config, "Cyclone configuration (default: CYCLONEDDS_URI)");
  CLI11_PARSE(app, argc, argv);

  try {
    cdc::dds::ParticipantOptions options;
    options.domain_id = cdc::dds::domain_from_env(0);
    options.config = config;
    cdc::dds::Participant participant(options);
    cdc::dds::Topic<cdc_msg_LidarScan> topic(participant, "cdc/bench/lidar_" + std::to_string(::getpid()));
    cdc::dds::Writer<cdc_msg_LidarScan> writer(participant, topic, cdc::dds::qos::sensor_stream(4, true));
    cdc::dds::Reader<cdc_msg_LidarScan> reader(participant, topic, cdc::dds::qos::sensor_stream(4, true));
    if (!writer.wait_for_readers(1, std::chrono::seconds(5))) {
      std::cerr << "cdc-bench-dds: the reader never matched the writer\n";
      return 1;
    }
    std::vector<cdc_msg_LidarPoint> storage(points);
    for (size_t i = 0; i < points; ++i) {
      const auto f = static_cast<float>(i);
      storage[i] = cdc_msg_LidarPoint{f * 0.01f, -f * 0.02f, 1.5f, 0.3f, f * 1e-6f, static_cast<uint16_t>(i % 16)};
    }
    cdc_msg_LidarScan scan{};
    scan.robot_id = 0;
    scan.duration_ns = 100'000'000;
    scan.point_count = static_cast<uint32_t>(points);
    scan.points._buffer = storage.data();
    scan.points._length = scan.points._maximum = static_cast<uint32_t>(points);
    scan.points._release = false;

    std::vector<double> write_ms, take_ms, size_ms, serialise_ms;
    size_t taken_points = 0;
    for (int r = 0; r < rounds; ++r) {
      scan.seq = static_cast<uint64_t>(r);
      scan.stamp_ns = static_cast<int64_t>(r) * 100'000'000;
      auto t0 = Clock::now();
      writer.write(scan);
      write_ms.push_back(ms_since(t0));
      t0 = Clock::now();
      const size_t bytes = cdc::dds::serialized_size(scan);
      size_ms.push_back(ms_since(t0));
      t0 = Clock::now();
      const size_t written = cdc::dds::serialized_size_by_writing(&cdc_msg_LidarScan_desc, &scan);
      serialise_ms.push_back(ms_since(t0));
      if (bytes != written) {
        std::cerr << "cdc-bench-dds: measured " << bytes << " bytes, serialised " << written << "\n";
        return 1;
      }
      for (int tries = 0;; ++tries) {
        t0 = Clock::now();
        const auto s = reader.take(4);
        const double dt = ms_since(t0);
        if (!s.empty()) {
          take_ms.push_back(dt);
          s.for_each_valid(
              [&](const cdc_msg_LidarScan& m, const dds_sample_info_t&) { taken_points += m.points._length; });
          break;
        }
        if (tries > 5000) {
          std::cerr << "cdc-bench-dds: sweep " << r << " never arrived\n";
          return 1;
        }
        ::usleep(100);
      }
    }
    const auto totals = cdc::dds::topic_traffic().at({topic.domain(), topic.name()});
    nlohmann::json j{{"points", points},
                     {"rounds", rounds},
                     {"write_ms_median", median(write_ms)},
                     {"take_ms_median", median(take_ms)},
                     {"measure_size_ms_median", median(size_ms)},
                     {"serialise_again_ms_median", median(serialise_ms)},
                     {"points_taken", taken_points},
                     {"bytes_per_sweep", totals.bytes_written / static_cast<uint64_t>(rounds)},
                     {"bytes_taken_equal_written", totals.bytes_taken == totals.bytes_written}};
    std::printf(
        "sweep of %zu points: write %.3f ms, take %.3f ms, measuring its size %.4f ms, serialising it again "
        "%.3f ms (medians of %d)\n",
        points, median(write_ms), median(take_ms), median(size_ms), median(serialise_ms), rounds);
    std::cout << j.dump() << "\n";
    return taken_points == points * static_cast<size_t>(rounds) ? 0 : 1;
  } catch (const std::exception& e) {
    std::cerr << "cdc-bench-dds: " << e.what() << "\n";
    return 1;
  }
}
