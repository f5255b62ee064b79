// VelodyneDriverCore on the real VLP-16 packets of the nebula fixture (CDC_DATA_DIR): the same sweeps
// as a VelodyneSweepAssembler with cdc-import's settings, bad datagrams counted and harmless; the
// replay pacer; the configuration file.
#include "cdc/velodyne_driver/velodyne_driver_core.hpp"

#include "cdc/config/reader.hpp"
#include "velodyne_fixture.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace cdc::velodyne_driver {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr uint16_t kPort = 2368;

using test::velodyne_fixture_dir;
using test::vlp16_packets;
using Packet = test::VelodynePacket;

VelodyneDriverConfig vlp16_config() {
  VelodyneDriverConfig c;
  c.decoder.model = io::VelodyneModel::kVLP16;
  c.calibration = test::vlp16_calibration();
  return c;
}

std::vector<DriverSweep> drain(VelodyneDriverCore& core) {
  std::vector<DriverSweep> out;
  while (auto s = core.next_sweep()) out.push_back(std::move(*s));
  return out;
}

#define SKIP_WITHOUT_FIXTURE(packets) \
  if ((packets).empty()) GTEST_SKIP() << "no Velodyne fixture under " << velodyne_fixture_dir() << " (set CDC_DATA_DIR)"

TEST(VelodyneDriverCore, SameSweepsAsTheAssemblerWithImportSettings) {
  const std::vector<Packet> packets = vlp16_packets();
  SKIP_WITHOUT_FIXTURE(packets);
  const VelodyneDriverConfig config = vlp16_config();
  VelodyneDriverCore core(config);
  io::VelodyneDecoderOptions d;
  d.model = config.decoder.model;
  io::VelodyneSweepOptions so;
  so.emit_first = false;
  so.emit_incomplete = false;
  io::VelodyneSweepAssembler assembler(io::read_velodyne_calibration(config.calibration, config.decoder.model), d, so);
  std::vector<DriverSweep> sweeps;
  std::vector<io::VelodyneSweep> reference;
  for (const Packet& p : packets) {
    EXPECT_EQ(core.add_datagram(p.data, p.stamp_ns, kPort), DatagramStatus::kOk);
    for (DriverSweep& s : drain(core)) sweeps.push_back(std::move(s));
    assembler.add_packet(p.data, p.stamp_ns);
    while (assembler.has_sweep()) reference.push_back(assembler.take());
  }
  core.end_of_stream();
  EXPECT_TRUE(drain(core).empty()) << "the sweep in progress at the end is incomplete: never published";
  ASSERT_GT(reference.size(), 0u);
  ASSERT_EQ(sweeps.size(), reference.size());
  EXPECT_EQ(core.stats().sweeps, sweeps.size());
  EXPECT_EQ(core.stats().ok, packets.size());
  EXPECT_EQ(core.stats().datagrams, packets.size());
  uint64_t points = 0;
  for (size_t i = 0; i < sweeps.size(); ++i) {
    const DriverSweep& s = sweeps[i];
    EXPECT_EQ(s.seq, i);
    EXPECT_EQ(s.sweep.points.size(), reference[i].points.size());
    EXPECT_EQ(s.packets, reference[i].packets);
    if (i > 0) {
      EXPECT_GT(s.stamp_ns, sweeps[i - 1].stamp_ns);
    }
    // A VLP-16 turns in 0.1 s: the sweep spans about that (plus the points carried over the cut).
    EXPECT_GT(s.duration_ns, 80'000'000);
    EXPECT_LT(s.duration_ns, 130'000'000);
    float max_offset = 0.0f;
    for (const io::CloudPoint& p : s.sweep.points) {
      ASSERT_GE(p.time_offset, 0.0f);
      ASSERT_LE(static_cast<double>(p.time_offset), static_cast<double>(s.duration_ns) * 1e-9 + 1e-6);
      ASSERT_LT(p.ring, 16);
      ASSERT_GE(p.intensity, 0.0f);
      ASSERT_LE(p.intensity, 1.0f);
      max_offset = std::max(max_offset, p.time_offset);
    }
    EXPECT_NEAR(static_cast<double>(max_offset), static_cast<double>(s.duration_ns) * 1e-9, 1e-6);
    points += s.sweep.points.size();
  }
  EXPECT_EQ(core.stats().points, points);
  std::printf("%zu packets -> %zu sweeps, %llu points\n", packets.size(), sweeps.size(),
              static_cast<unsigned long long>(points));
}

TEST(VelodyneDriverCore, BadDatagramsAreCountedAndChangeNothing) {
  const std::vector<Packet> packets = vlp16_packets();
  SKIP_WITHOUT_FIXTURE(packets);
  VelodyneDriverCore clean(vlp16_config()), noisy(vlp16_config());
  std::vector<DriverSweep> expected, got;
  size_t bad = 0;
  for (size_t i = 0; i < packets.size(); ++i) {
    const Packet& p = packets[i];
    clean.add_datagram(p.data, p.stamp_ns, kPort);
    for (DriverSweep& s : drain(clean)) expected.push_back(std::move(s));
    if (i % 50 == 7) {  // a few bad datagrams before the good one, each with the good one's stamp
      const std::vector<uint8_t> truncated(p.data.begin(), p.data.begin() + 600);
      EXPECT_EQ(noisy.add_datagram(truncated, p.stamp_ns, kPort), DatagramStatus::kTruncated);
      EXPECT_EQ(noisy.add_datagram({}, p.stamp_ns, kPort), DatagramStatus::kTruncated);
      std::vector<uint8_t> longer = p.data;
      longer.push_back(0);
      EXPECT_EQ(noisy.add_datagram(longer, p.stamp_ns, kPort), DatagramStatus::kMalformed);
      EXPECT_EQ(noisy.add_datagram(std::vector<uint8_t>(70000, 0xEE), p.stamp_ns, kPort), DatagramStatus::kMalformed);
      std::vector<uint8_t> bad_block = p.data;
      bad_block[0] = bad_block[1] = 0;  // block 0's id is 0xEEFF
      EXPECT_EQ(noisy.add_datagram(bad_block, p.stamp_ns, kPort), DatagramStatus::kMalformed);
      std::vector<uint8_t> bad_mode = p.data;
      bad_mode[1204] = 0x42;
      EXPECT_EQ(noisy.add_datagram(bad_mode, p.stamp_ns, kPort), DatagramStatus::kMalformed);
      std::vector<uint8_t> other_model = p.data;
      other_model[1205] = 0x28;  // a VLP-32C's product id
      EXPECT_EQ(noisy.add_datagram(other_model, p.stamp_ns, kPort), DatagramStatus::kWrongModel);
      EXPECT_EQ(noisy.add_datagram(std::vector<uint8_t>(512, 0), p.stamp_ns, 8308), DatagramStatus::kOtherPort);
      EXPECT_EQ(noisy.add_datagram(p.data, p.stamp_ns, 2369), DatagramStatus::kOtherPort);
      bad += 9;
    }
    EXPECT_EQ(noisy.add_datagram(p.data, p.stamp_ns, kPort), DatagramStatus::kOk) << "packet " << i;
    for (DriverSweep& s : drain(noisy)) got.push_back(std::move(s));
  }
  const size_t rounds = bad / 9;
  ASSERT_GT(expected.size(), 0u);
  ASSERT_EQ(got.size(), expected.size());
  for (size_t i = 0; i < got.size(); ++i) {
    EXPECT_EQ(got[i].stamp_ns, expected[i].stamp_ns);
    EXPECT_EQ(got[i].sweep.points.size(), expected[i].sweep.points.size());
  }
  const DriverStats& s = noisy.stats();
  EXPECT_EQ(s.datagrams, packets.size() + bad);
  EXPECT_EQ(s.ok, packets.size());
  EXPECT_EQ(s.truncated, 2 * rounds);
  EXPECT_EQ(s.malformed, 4 * rounds);
  EXPECT_EQ(s.wrong_model, rounds);
  EXPECT_EQ(s.other_port, 2 * rounds);
  EXPECT_EQ(s.out_of_order, 0u);
}

TEST(VelodyneDriverCore, PacketsGoingBackAreOutOfOrder) {
  const std::vector<Packet> packets = vlp16_packets();
  SKIP_WITHOUT_FIXTURE(packets);
  VelodyneDriverCore core(vlp16_config());
  for (size_t i = 0; i < 20; ++i)
    ASSERT_EQ(core.add_datagram(packets[i].data, packets[i].stamp_ns, kPort), DatagramStatus::kOk);
  EXPECT_EQ(core.add_datagram(packets[10].data, packets[10].stamp_ns, kPort),
            DatagramStatus::kOutOfOrder);  // older stamp
  EXPECT_EQ(core.add_datagram(packets[10].data, packets[19].stamp_ns, kPort),
            DatagramStatus::kOutOfOrder);  // azimuth back
  EXPECT_EQ(core.stats().out_of_order, 2u);
}

TEST(VelodyneDriverCore, ASilenceDropsTheSweepItInterrupts) {
  const std::vector<Packet> packets = vlp16_packets();
  SKIP_WITHOUT_FIXTURE(packets);
  VelodyneDriverCore whole(vlp16_config()), broken(vlp16_config());
  std::vector<DriverSweep> a, b;
  // One second of silence a quarter turn into a sweep (packet boundaries of the bag's messages avoided).
  const size_t middle = packets.size() / 2 + 40;
  for (size_t i = 0; i < packets.size(); ++i) {
    whole.add_datagram(packets[i].data, packets[i].stamp_ns, kPort);
    for (DriverSweep& s : drain(whole)) a.push_back(std::move(s));
    const int64_t shift = i >= middle ? 1'000'000'000 : 0;
    broken.add_datagram(packets[i].data, packets[i].stamp_ns + shift, kPort);
    for (DriverSweep& s : drain(broken)) b.push_back(std::move(s));
  }
  EXPECT_EQ(broken.stats().gaps, 1u);
  EXPECT_EQ(whole.stats().gaps, 0u);
  // The interrupted sweep's packets before the silence are dropped (incomplete), and so are those after
  // it up to the next cut (a part of a turn, like the first sweep of a stream): one sweep fewer, and
  // every sweep published is a whole one.
  ASSERT_EQ(b.size() + 1, a.size());
  size_t ai = 0;
  for (const DriverSweep& s : b) {
    while (ai < a.size() && a[ai].packets != s.packets) ++ai;
    ASSERT_LT(ai, a.size()) << "a sweep of " << s.packets << " packets that the uninterrupted stream does not have";
    ++ai;
  }
}

TEST(VelodyneDriverCore, NeedsACalibrationOrAModel) {
  VelodyneDriverConfig c;
  c.decoder.model.reset();
  EXPECT_THROW(VelodyneDriverCore{c}, std::invalid_argument);
  c.decoder.model = io::VelodyneModel::kVLP32C;
  VelodyneDriverCore built_in(c);
  EXPECT_EQ(built_in.calibration().lasers.size(), 32u);
  c.calibration = "/nonexistent/VLP32.yaml";
  EXPECT_THROW(VelodyneDriverCore{c}, io::FormatError);
  c.calibration.clear();
  c.decoder.min_range = 300;
  EXPECT_THROW(VelodyneDriverCore{c}, std::invalid_argument);
}

TEST(VelodyneDriverCore, GarbageWithoutFixturesNeverThrows) {
  VelodyneDriverCore core(VelodyneDriverConfig{});  // the built-in VLP-16 table
  std::vector<uint8_t> buf;
  uint32_t x = 12345;
  for (int i = 0; i < 2000; ++i) {
    buf.resize(static_cast<size_t>(i % 3 == 0 ? 1206 : i));
    for (uint8_t& b : buf) {
      x = x * 1664525u + 1013904223u;  // a fixed LCG: the same bytes every run
      b = static_cast<uint8_t>(x >> 24);
    }
    EXPECT_NO_THROW(core.add_datagram(buf, int64_t{1'000'000} * i, kPort));
    EXPECT_NO_THROW(drain(core));
  }
  const DriverStats& s = core.stats();
  EXPECT_EQ(s.datagrams, 2000u);
  EXPECT_EQ(s.ok + s.truncated + s.malformed + s.wrong_model + s.out_of_order + s.other_port, 2000u);
  EXPECT_EQ(s.ok, 0u) << "random bytes decoded as a packet";
}

TEST(ReplayPacer, ScalesCaptureTimeByTheRate) {
  ReplayPacer real(1.0), twice(2.0), fast(0.0);
  EXPECT_FALSE(real.due(5'000'000'000).has_value());  // the first is due at once
  EXPECT_EQ(real.due(5'100'000'000), std::chrono::nanoseconds(100ms));
  EXPECT_FALSE(real.due(4'000'000'000).has_value()) << "a clock stepping back";
  EXPECT_FALSE(twice.due(1'000'000'000).has_value());
  EXPECT_EQ(twice.due(1'200'000'000), std::chrono::nanoseconds(100ms));
  EXPECT_FALSE(fast.due(1).has_value());
  EXPECT_FALSE(fast.due(1'000'000'000).has_value());
}

TEST(VelodyneDriverConfig, TheShippedFileHoldsTheDefaults) {
  const VelodyneDriverConfig d, f = load_driver_config(CDC_VELODYNE_YAML);
  EXPECT_EQ(f.decoder.model, d.decoder.model);
  EXPECT_TRUE(f.calibration.empty());
  EXPECT_EQ(f.decoder.return_mode, d.decoder.return_mode);
  EXPECT_EQ(f.decoder.rpm, d.decoder.rpm);
  EXPECT_EQ(f.scan_phase_deg, d.scan_phase_deg);
  EXPECT_EQ(f.max_gap, d.max_gap);
  EXPECT_EQ(f.decoder.min_range, d.decoder.min_range);
  EXPECT_EQ(f.decoder.max_range, d.decoder.max_range);
  EXPECT_EQ(f.decoder.sector_min_deg, d.decoder.sector_min_deg);
  EXPECT_EQ(f.decoder.sector_max_deg, d.decoder.sector_max_deg);
  EXPECT_EQ(f.port, d.port);
  EXPECT_EQ(f.receive_buffer_bytes, d.receive_buffer_bytes);
  EXPECT_EQ(f.log_level, d.log_level);
}

TEST(VelodyneDriverConfig, ReadsKeysAndListsEveryError) {
  const fs::path dir = fs::temp_directory_path() / ("cdc_velodyne_config_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "good.yaml") << "sensor:\n  model: vlp-32c\n  calibration: cal/VLP32.yaml\n  return_mode: dual\n"
                                      "sweep:\n  scan_phase_deg: 180\n  max_gap_ms: 20\nudp:\n  port: 2370\n";
  const VelodyneDriverConfig g = load_driver_config((dir / "good.yaml").string());
  EXPECT_EQ(g.decoder.model, io::VelodyneModel::kVLP32C);
  EXPECT_EQ(g.calibration, dir / "cal" / "VLP32.yaml");
  EXPECT_EQ(g.decoder.return_mode, io::VelodyneReturnMode::kDual);
  EXPECT_EQ(g.scan_phase_deg, 180.0);
  EXPECT_EQ(g.max_gap, std::chrono::nanoseconds(20ms));
  EXPECT_EQ(g.port, 2370);
  std::ofstream(dir / "auto.yaml") << "sensor:\n  model: auto\n";
  EXPECT_FALSE(load_driver_config((dir / "auto.yaml").string()).decoder.model.has_value());
  std::ofstream(dir / "bad.yaml") << "sensor:\n  model: HDL-99\n  return_mode: both\nudp:\n  port: 70000\n"
                                     "filter:\n  min_range_m: 5\n  max_range_m: 2\nspeed: 3\n";
  try {
    load_driver_config((dir / "bad.yaml").string());
    ADD_FAILURE() << "a bad configuration was accepted";
  } catch (const config::ConfigError& e) {
    const std::string what = e.what();
    for (const char* key : {"sensor.model", "sensor.return_mode", "udp.port", "min_range_m", "speed"}) {
      EXPECT_NE(what.find(key), std::string::npos) << key << " not named in: " << what;
    }
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace cdc::velodyne_driver
