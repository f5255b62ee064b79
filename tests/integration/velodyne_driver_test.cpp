// cdc-velodyne with real processes (loopback configuration) on the real VLP-16 packets of the nebula
// fixture (CDC_DATA_DIR): a pcap replay at sensor rate reaches cdc-frontend, and the sweeps the driver
// publishes, the sweeps the front-end processes and the sweeps `cdc-import bag` makes of the same
// packets are the same number; and the same packets sent as UDP datagrams to 127.0.0.1, with malformed
// ones among them, come out as the same sweeps with the bad datagrams counted.
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/topics.hpp"
#include "cdc/dds/validate.hpp"
#include "cdc/io/pcap.hpp"
#include "cdc/io/velodyne.hpp"
#include "child_process.hpp"
#include "process_test.hpp"
#include "velodyne_fixture.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

namespace cdc {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

using Packet = test::VelodynePacket;
using test::vlp16_bag;
using test::vlp16_calibration;
using test::vlp16_packets;

// Sweeps a VelodyneSweepAssembler makes of the packets with cdc-import's settings.
size_t reference_sweeps(const std::vector<Packet>& packets) {
  io::VelodyneDecoderOptions d;
  d.model = io::VelodyneModel::kVLP16;
  io::VelodyneSweepOptions so;
  so.emit_first = false;
  so.emit_incomplete = false;
  io::VelodyneSweepAssembler a(io::read_velodyne_calibration(vlp16_calibration(), d.model), d, so);
  size_t n = 0;
  for (const Packet& p : packets) {
    a.add_packet(p.data, p.stamp_ns);
    for (; a.has_sweep(); ++n) a.take();
  }
  return n;
}

nlohmann::json read_json(const fs::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

bool exited_zero(const std::optional<int>& status) { return status && WIFEXITED(*status) && WEXITSTATUS(*status) == 0; }

std::string text_of(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

class VelodyneDriver : public test::ProcessTest {
 protected:
  VelodyneDriver() : ProcessTest("velodyne_driver", {"CDC_VELODYNE_BIN", "CDC_FRONTEND_BIN", "CDC_IMPORT_BIN"}) {}

  void set_up() override {
    if (!fs::exists(vlp16_bag())) GTEST_SKIP() << "no Velodyne fixture at " << vlp16_bag() << " (set CDC_DATA_DIR)";
    packets_ = vlp16_packets();
  }

  std::vector<std::string> driver_args(const std::string& stats) const {
    return {std::getenv("CDC_VELODYNE_BIN"),
            "--robot",
            "0",
            "--model",
            "VLP16",
            "--calibration",
            vlp16_calibration().string(),
            "--stats-out",
            (dir_ / stats).string()};
  }

  std::vector<Packet> packets_;
};

TEST_F(VelodyneDriver, PcapReplayReachesTheFrontEndWithTheSweepsCdcImportMakes) {
  // (a) The fixture's packets as a capture: data to port 2368, and now and then a datagram to the
  // position port 8308, which the driver must count and leave alone.
  const fs::path pcap = dir_ / "vlp16.pcap";
  uint64_t position_packets = 0;
  {
    io::PcapWriter w(pcap);
    for (size_t i = 0; i < packets_.size(); ++i) {
      io::UdpDatagram d;
      d.stamp_ns = packets_[i].stamp_ns;
      d.src_ip = d.dst_ip = 0x7F000001;
      d.src_port = d.dst_port = 2368;
      d.payload = packets_[i].data;
      w.write(d);
      if (i % 100 == 50) {
        d.dst_port = d.src_port = 8308;
        d.payload.assign(512, 0);
        w.write(d);
        ++position_packets;
      }
    }
  }
  // cdc-import's sweeps of the same packets.
  test::ChildProcess importer =
      test::ChildProcess::spawn({std::getenv("CDC_IMPORT_BIN"), "bag", vlp16_bag().string(), "--calibration",
                                 vlp16_calibration().string(), "--model", "VLP16", "--out", (dir_ / "ds").string()},
                                (dir_ / "import.log").string());
  ASSERT_TRUE(exited_zero(importer.wait(60s))) << "see " << dir_ / "import.log";
  size_t imported = 0;
  {
    std::ifstream times(dir_ / "ds" / "robot_0" / "times.txt");
    for (std::string line; std::getline(times, line);) imported += line.empty() ? 0u : 1u;
  }

  // (b) The front-end of robot 0, LiDAR only; the test watches its odometry to know when it is done.
  dds::Participant& participant = *participant_;
  dds::Topic<cdc_msg_Odometry> t_odom(participant, dds::topics::kOdometry);
  dds::Reader<cdc_msg_Odometry> r_odom(
      participant, t_odom, dds::qos::sensor_stream(64, true).partitions(dds::partitions::all_robots_reader()));
  std::ofstream(dir_ / "frontend.yaml") << "robots: 1\nimu:\n  use: false\n";
  test::ChildProcess fe =
      test::ChildProcess::spawn({std::getenv("CDC_FRONTEND_BIN"), "--robot", "0", "--config",
                                 (dir_ / "frontend.yaml").string(), "--stats-out", (dir_ / "frontend.json").string()},
                                (dir_ / "frontend.log").string());
  ASSERT_TRUE(r_odom.wait_for_writers(1, 15s)) << "the front-end did not come up, see " << dir_ / "frontend.log";

  // (c) The replay at sensor rate, once the front-end's reader has matched.
  std::vector<std::string> args = driver_args("driver.json");
  for (const char* a : {"--pcap", pcap.c_str(), "--rate", "1", "--wait-readers", "1"}) args.emplace_back(a);
  const auto started = std::chrono::steady_clock::now();
  test::ChildProcess driver = test::ChildProcess::spawn(args, (dir_ / "driver.log").string());
  ASSERT_TRUE(exited_zero(driver.wait(60s))) << "see " << dir_ / "driver.log";
  const auto replay_time = std::chrono::steady_clock::now() - started;
  const nlohmann::json ds = read_json(dir_ / "driver.json");
  const size_t published = ds["published"].get<size_t>();
  size_t odometry = 0;
  for (auto deadline = std::chrono::steady_clock::now() + 30s;
       odometry < published && std::chrono::steady_clock::now() < deadline;) {
    r_odom.take(64).for_each_valid(
        [&](const cdc_msg_Odometry& m, const dds_sample_info_t&) { odometry += m.robot_id == 0 ? 1u : 0u; });
    std::this_thread::sleep_for(20ms);
  }
  fe.signal(SIGTERM);
  ASSERT_TRUE(exited_zero(fe.wait(15s))) << "see " << dir_ / "frontend.log";
  const nlohmann::json fs_ = read_json(dir_ / "frontend.json");

  // (d) Every count equal, and not zero.
  std::printf(
      "cdc-import %zu sweeps, driver %zu published (%llu datagrams, %llu points), front-end %zu scans / %zu odometry\n",
      imported, published, static_cast<unsigned long long>(ds["datagrams"].get<uint64_t>()),
      static_cast<unsigned long long>(ds["points"].get<uint64_t>()), fs_["scans"].get<size_t>(),
      fs_["odometry"].get<size_t>());
  EXPECT_GT(imported, 0u);
  EXPECT_EQ(published, imported);
  EXPECT_EQ(ds["sweeps"].get<size_t>(), published);
  EXPECT_EQ(fs_["scans"].get<size_t>(), published);
  EXPECT_EQ(fs_["odometry"].get<size_t>(), published);
  EXPECT_EQ(odometry, published);
  EXPECT_EQ(fs_["rejected_samples"].get<uint64_t>(), 0u);
  EXPECT_EQ(ds["packets"]["ok"].get<size_t>(), packets_.size());
  EXPECT_EQ(ds["packets"]["other_port"].get<uint64_t>(), position_packets);
  EXPECT_EQ(ds["datagrams"].get<size_t>(), packets_.size() + position_packets);
  EXPECT_EQ(ds["pcap_records"].get<size_t>(), packets_.size() + position_packets);
  EXPECT_EQ(ds["error"].get<std::string>(), "");
  // Paced at the capture's rate, the replay lasts at least as long as the capture.
  EXPECT_GE(replay_time, std::chrono::nanoseconds(packets_.back().stamp_ns - packets_.front().stamp_ns));
  EXPECT_NE(text_of(dir_ / "driver.log").find("stopped after " + std::to_string(published) + " sweeps"),
            std::string::npos);
}

// A free UDP port on 127.0.0.1, chosen by the kernel.
uint16_t free_udp_port() {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  a.sin_port = 0;
  socklen_t len = sizeof a;
  if (fd < 0 || ::bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0 ||
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len) != 0) {
    if (fd >= 0) ::close(fd);
    return 0;
  }
  ::close(fd);
  return ntohs(a.sin_port);
}

TEST_F(VelodyneDriver, UdpDatagramsOnLoopbackWithMalformedOnesCounted) {
  const uint16_t port = free_udp_port();
  ASSERT_NE(port, 0);
  dds::Participant& participant = *participant_;
  dds::Topic<cdc_msg_LidarScan> t_scan(participant, dds::topics::kLidar);
  dds::Reader<cdc_msg_LidarScan> r_scan(participant, t_scan, dds::qos::sensor_stream(16, true));
  // This test sends the packets from a thread of its own, which a loaded machine can stall for longer
  // than the 50 ms silence that ends a sweep: what is tested here is the datagrams, not the silences.
  std::ofstream(dir_ / "driver.yaml") << "sweep:\n  max_gap_ms: 5000\n";
  std::vector<std::string> args = driver_args("driver.json");
  for (const std::string& a : {std::string("--bind"), std::string("127.0.0.1"), std::string("--port"),
                               std::to_string(port), std::string("--config"), (dir_ / "driver.yaml").string()})
    args.push_back(a);
  test::ChildProcess driver = test::ChildProcess::spawn(args, (dir_ / "driver.log").string());
  ASSERT_TRUE(r_scan.wait_for_writers(1, 15s)) << "see " << dir_ / "driver.log";
  // The socket is bound right after the writer is made; the log says when.
  ASSERT_TRUE(dds::wait_until(
      [&] { return text_of(dir_ / "driver.log").find("listening on UDP") != std::string::npos; }, 15000ms))
      << "see " << dir_ / "driver.log";

  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  to.sin_port = htons(port);
  const auto send = [&](const std::vector<uint8_t>& payload) {
    ASSERT_EQ(::sendto(fd, payload.data(), payload.size(), 0, reinterpret_cast<const sockaddr*>(&to), sizeof to),
              static_cast<ssize_t>(payload.size()));
  };
  // The packets at the capture's pace; before every 60th, a truncated one, an empty one, one too long
  // and one whose first block id is broken.
  uint64_t truncated = 0, malformed = 0;
  const auto start = std::chrono::steady_clock::now();
  for (size_t i = 0; i < packets_.size(); ++i) {
    std::this_thread::sleep_until(start + std::chrono::nanoseconds(packets_[i].stamp_ns - packets_.front().stamp_ns));
    const std::vector<uint8_t>& p = packets_[i].data;
    if (i % 60 == 30) {
      send(std::vector<uint8_t>(p.begin(), p.begin() + 100));
      send({});
      std::vector<uint8_t> longer = p;
      longer.resize(1300, 0);
      send(longer);
      std::vector<uint8_t> broken = p;
      broken[0] = broken[1] = 0;
      send(broken);
      truncated += 2;
      malformed += 2;
    }
    send(p);
  }
  ::close(fd);
  const size_t expected = reference_sweeps(packets_);
  std::vector<uint64_t> seqs;
  uint64_t points = 0;
  ASSERT_TRUE(dds::wait_until(
      [&] {
        r_scan.take(16).for_each_valid([&](const cdc_msg_LidarScan& m, const dds_sample_info_t&) {
          EXPECT_EQ(m.robot_id, 0u);
          const dds::Validation v = dds::validate(m, dds::ValidationLimits{});
          EXPECT_TRUE(v.is_ok()) << v.reason();
          EXPECT_GT(m.point_count, 0u);
          seqs.push_back(m.seq);
          points += m.point_count;
        });
        return seqs.size() >= expected;
      },
      20000ms))
      << seqs.size() << " of " << expected << " sweeps arrived";
  const auto stop = std::chrono::steady_clock::now();
  driver.signal(SIGTERM);
  ASSERT_TRUE(exited_zero(driver.wait(10s))) << "see " << dir_ / "driver.log";
  EXPECT_LT(std::chrono::steady_clock::now() - stop, 3s) << "shutdown is not prompt";

  const nlohmann::json ds = read_json(dir_ / "driver.json");
  std::printf(
      "UDP: %zu packets + %llu malformed + %llu truncated -> %zu sweeps (%llu points), kernel drops %llu, buffer %d "
      "bytes\n",
      packets_.size(), static_cast<unsigned long long>(malformed), static_cast<unsigned long long>(truncated),
      seqs.size(), static_cast<unsigned long long>(points),
      static_cast<unsigned long long>(ds["kernel_drops"].get<uint64_t>()), ds["receive_buffer_bytes"].get<int>());
  EXPECT_GT(expected, 0u);
  EXPECT_EQ(seqs.size(), expected);
  for (size_t i = 0; i < seqs.size(); ++i) EXPECT_EQ(seqs[i], i);
  EXPECT_EQ(ds["kernel_drops"].get<uint64_t>(), 0u);
  EXPECT_EQ(ds["port"].get<int>(), port);
  EXPECT_EQ(ds["sweeps"].get<size_t>(), expected);
  EXPECT_EQ(ds["published"].get<size_t>(), expected);
  EXPECT_EQ(ds["points"].get<uint64_t>(), points);
  EXPECT_EQ(ds["packets"]["ok"].get<size_t>(), packets_.size());
  EXPECT_EQ(ds["packets"]["truncated"].get<uint64_t>(), truncated);
  EXPECT_EQ(ds["packets"]["malformed"].get<uint64_t>(), malformed);
  EXPECT_EQ(ds["packets"]["out_of_order"].get<uint64_t>(), 0u);
  EXPECT_EQ(ds["datagrams"].get<size_t>(), packets_.size() + truncated + malformed);
}

}  // namespace
}  // namespace cdc
