// ROS 2 bags (sqlite3 folders, MCAP), the CDR decoders and PointCloud2 -> points.
//
// Fixtures are written at test time by make_ros2_fixtures.py (an independent writer that follows the
// format specifications); the expected values below follow the formulas in its docstring. The real
// Velodyne bags (nebula's decoder fixtures) are read from CDC_DATA_DIR.
#include "cdc/io/bag.hpp"
#include "cdc/io/ros_messages.hpp"

#include "ros2_bag.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <tuple>
#include <vector>

namespace cdc::io {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

constexpr int64_t kNs = 1'000'000'000;
constexpr std::string_view kPc2 = "sensor_msgs/msg/PointCloud2";
constexpr std::string_view kImu = "sensor_msgs/msg/Imu";
constexpr std::string_view kScan = "velodyne_msgs/msg/VelodyneScan";

int64_t cloud_stamp(int k) { return (1700000000LL + k) * kNs + 1000 * k + 500; }
int64_t imu_stamp(int k) { return (1700000000LL + k) * kNs + 250000000; }
int64_t scan_stamp(int k) { return (1700000100LL + k) * kNs; }

std::vector<uint8_t> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::vector<uint8_t>& bytes, size_t n) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(n));
}

std::vector<BagMessage> read_all(BagReader& reader) {
  std::vector<BagMessage> out;
  BagMessage m;
  while (reader.next(m)) out.push_back(m);
  return out;
}

// The message of `what` thrown as FormatError by f (empty and a test failure otherwise).
template <class F>
std::string format_error(F&& f) {
  try {
    f();
  } catch (const FormatError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no FormatError thrown";
  return {};
}

class Ros2Bags : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new fs::path(fs::temp_directory_path() / ("cdc_ros2_bag_test_" + std::to_string(::getpid())));
    fs::remove_all(*dir_);
    fs::create_directories(*dir_);
    const std::string cmd =
        std::string("\"") + CDC_PYTHON3 + "\" \"" + CDC_ROS2_FIXTURE_SCRIPT + "\" \"" + dir_->string() + "\"";
    fixtures_ok_ = std::system(cmd.c_str()) == 0;
    if (fixtures_ok_) {
      std::ifstream in(*dir_ / "fixtures.json");
      info_ = new nlohmann::json(nlohmann::json::parse(in));
    }
  }
  static void TearDownTestSuite() {
    fs::remove_all(*dir_);
    delete dir_;
    delete info_;
    info_ = nullptr;
  }
  void SetUp() override { ASSERT_TRUE(fixtures_ok_) << "make_ros2_fixtures.py failed"; }

  static fs::path dir() { return *dir_; }
  static const nlohmann::json& info() { return *info_; }

  static fs::path* dir_;
  static nlohmann::json* info_;
  static bool fixtures_ok_;
};
fs::path* Ros2Bags::dir_ = nullptr;
nlohmann::json* Ros2Bags::info_ = nullptr;
bool Ros2Bags::fixtures_ok_ = false;

// ------------------------------------------------------------------ expected fixture contents

void expect_cloud_k(const BagMessage& m, int k) {
  const PointCloud2Msg c = decode_point_cloud2(m);
  EXPECT_EQ(c.header.stamp_ns, cloud_stamp(k));
  EXPECT_EQ(c.header.frame_id, "lidar");
  EXPECT_EQ(c.height, 1u);
  EXPECT_EQ(c.width, 10u);
  ASSERT_EQ(c.fields.size(), 6u);
  const std::vector<std::tuple<std::string, uint32_t, uint8_t>> fields = {
      {"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 12, 7}, {"ring", 16, 4}, {"time", 20, 7}};
  for (size_t i = 0; i < fields.size(); ++i) {
    EXPECT_EQ(c.fields[i].name, std::get<0>(fields[i]));
    EXPECT_EQ(c.fields[i].offset, std::get<1>(fields[i]));
    EXPECT_EQ(c.fields[i].datatype, std::get<2>(fields[i]));
    EXPECT_EQ(c.fields[i].count, 1u);
  }
  EXPECT_FALSE(c.is_bigendian);
  EXPECT_EQ(c.point_step, 24u);
  EXPECT_EQ(c.row_step, 240u);
  EXPECT_EQ(c.data.size(), 240u);
  EXPECT_FALSE(c.is_dense);

  const DecodedCloud d = cloud_points(c);
  EXPECT_TRUE(d.has_time);
  EXPECT_TRUE(d.has_ring);
  EXPECT_TRUE(d.has_intensity);
  EXPECT_EQ(d.time_field, "time");
  EXPECT_EQ(d.ring_field, "ring");
  ASSERT_EQ(d.points.size(), 9u);  // point 3 is NaN
  size_t j = 0;
  for (int i = 0; i < 10; ++i) {
    if (i == 3) continue;
    const CloudPoint& p = d.points[j++];
    EXPECT_EQ(p.x, static_cast<float>(k + i / 2.0)) << i;
    EXPECT_EQ(p.y, static_cast<float>(-i / 4.0));
    EXPECT_EQ(p.z, static_cast<float>(1 + i / 8.0));
    EXPECT_EQ(p.intensity, static_cast<float>(3 * i));
    EXPECT_EQ(p.ring, i % 16);
    EXPECT_EQ(p.time_offset, static_cast<float>(i / 1024.0));
  }
}

// with_covariances: the ROS 1 decoder (ros1_messages.cpp) does not fill the covariances yet.
void expect_imu_values(const ImuMsg& imu, int k, bool with_covariances = true) {
  EXPECT_EQ(imu.header.stamp_ns, imu_stamp(k));
  EXPECT_EQ(imu.header.frame_id, "imu");
  EXPECT_EQ(imu.orientation.x(), k / 8.0);
  EXPECT_EQ(imu.orientation.y(), -k / 16.0);
  EXPECT_EQ(imu.orientation.z(), 0.25);
  EXPECT_EQ(imu.orientation.w(), 1.0);
  EXPECT_EQ(imu.angular_velocity, Eigen::Vector3d(k / 4.0, -k / 2.0, 1.0 + k));
  EXPECT_EQ(imu.linear_acceleration, Eigen::Vector3d(0.5, -0.25, 9.8125 + k / 16.0));
  for (size_t j = 0; with_covariances && j < 9; ++j) {
    const double c = k + static_cast<double>(j) / 4.0;
    EXPECT_EQ(imu.orientation_covariance[j], c);
    EXPECT_EQ(imu.angular_velocity_covariance[j], c);
    EXPECT_EQ(imu.linear_acceleration_covariance[j], c);
  }
}

void expect_scan_k(const BagMessage& m, int k) {
  const VelodyneScanMsg s = decode_velodyne_scan(m);
  EXPECT_EQ(s.header.stamp_ns, scan_stamp(k));
  EXPECT_EQ(s.header.frame_id, "velodyne");
  ASSERT_EQ(s.packets.size(), 3u);
  for (int p = 0; p < 3; ++p) {
    const auto& pk = s.packets[static_cast<size_t>(p)];
    EXPECT_EQ(pk.stamp_ns, scan_stamp(k) + 1000 * p);
    for (size_t j = 0; j < 1204; ++j) {
      const uint8_t expected =
          j >= 100 && j < 600 ? 0 : static_cast<uint8_t>((7 * k + 3 * p + static_cast<int>(j)) & 0xff);
      ASSERT_EQ(pk.data[j], expected) << "packet " << p << " byte " << j;
    }
    EXPECT_EQ(pk.data[1204], 0x37);
    EXPECT_EQ(pk.data[1205], 0x22);
  }
}

void expect_cloud_be(const BagMessage& m) {
  const PointCloud2Msg c = decode_point_cloud2(m);
  EXPECT_EQ(c.header.stamp_ns, cloud_stamp(7));
  EXPECT_TRUE(c.is_bigendian);
  EXPECT_EQ(c.point_step, 32u);
  const DecodedCloud d = cloud_points(c);
  EXPECT_TRUE(d.has_time && d.has_ring && d.has_intensity);
  EXPECT_EQ(d.time_field, "t");
  ASSERT_EQ(d.points.size(), 6u);
  for (int i = 0; i < 6; ++i) {
    const CloudPoint& p = d.points[static_cast<size_t>(i)];
    EXPECT_EQ(p.x, static_cast<float>(7 + i / 2.0));
    EXPECT_EQ(p.y, static_cast<float>(-i / 4.0));
    EXPECT_EQ(p.z, static_cast<float>(1 + i / 8.0));
    EXPECT_EQ(p.intensity, static_cast<float>(3 * i));
    EXPECT_EQ(p.ring, i);
    EXPECT_FLOAT_EQ(p.time_offset, static_cast<float>(1000 * i * 1e-9));
  }
}

void expect_cloud_abs(const BagMessage& m) {
  const DecodedCloud d = cloud_points(decode_point_cloud2(m));
  EXPECT_TRUE(d.has_time);
  EXPECT_EQ(d.time_field, "timestamp");
  EXPECT_FALSE(d.has_ring);
  EXPECT_FALSE(d.has_intensity);
  ASSERT_EQ(d.points.size(), 4u);
  for (int i = 0; i < 4; ++i) {
    const CloudPoint& p = d.points[static_cast<size_t>(i)];
    EXPECT_EQ(p.x, static_cast<float>(5 + i / 2.0));
    EXPECT_NEAR(p.time_offset, i / 256.0, 1e-6);  // absolute float64 seconds resolve ~0.24 us
    EXPECT_EQ(p.ring, 0);
    EXPECT_EQ(p.intensity, 0.0f);
  }
}

// The 13 CDR messages every ROS 2 fixture holds: topic and log time, in log-time order.
std::vector<std::pair<std::string, int64_t>> expected_order() {
  std::vector<std::pair<std::string, int64_t>> v;
  for (int k = 0; k < 4; ++k) v.emplace_back("/points", cloud_stamp(k) + 1000000);
  for (int k = 0; k < 5; ++k) v.emplace_back("/imu", imu_stamp(k) + 2000000);
  for (int k = 0; k < 2; ++k) v.emplace_back("/velodyne_packets", scan_stamp(k) + 5000000);
  v.emplace_back("/points_be", cloud_stamp(7) + 1000000);
  v.emplace_back("/points_abs", cloud_stamp(5) + 1000000);
  std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.second < b.second; });
  return v;
}

void expect_fixture_messages(const std::vector<BagMessage>& all) {
  std::vector<BagMessage> msgs;
  for (const auto& m : all) {
    if (m.serialization == Serialization::kCdr) msgs.push_back(m);
  }
  const auto order = expected_order();
  ASSERT_EQ(msgs.size(), order.size());
  for (size_t i = 0; i < msgs.size(); ++i) {
    const BagMessage& m = msgs[i];
    SCOPED_TRACE(m.topic + " @ " + std::to_string(m.log_time_ns));
    ASSERT_EQ(m.topic, order[i].first) << i;
    ASSERT_EQ(m.log_time_ns, order[i].second) << i;
    if (m.topic == "/points") {
      EXPECT_EQ(m.type, kPc2);
      expect_cloud_k(m, static_cast<int>((m.log_time_ns - 1000000) / kNs - 1700000000));
    } else if (m.topic == "/imu") {
      EXPECT_EQ(m.type, kImu);
      expect_imu_values(decode_imu(m), static_cast<int>((m.log_time_ns - 2000000) / kNs - 1700000000));
    } else if (m.topic == "/velodyne_packets") {
      EXPECT_EQ(m.type, kScan);
      expect_scan_k(m, static_cast<int>((m.log_time_ns - 5000000) / kNs - 1700000100));
    } else if (m.topic == "/points_be") {
      expect_cloud_be(m);
    } else {
      expect_cloud_abs(m);
    }
  }
}

std::map<std::string, BagTopic> topic_map(const BagReader& r) {
  std::map<std::string, BagTopic> out;
  for (const auto& t : r.topics()) out[t.name] = t;
  return out;
}

void expect_fixture_topics(const BagReader& r) {
  auto t = topic_map(r);
  EXPECT_EQ(t["/points"].messages, 4u);
  EXPECT_EQ(t["/points"].type, kPc2);
  EXPECT_EQ(t["/imu"].messages, 5u);
  EXPECT_EQ(t["/imu"].type, kImu);
  EXPECT_EQ(t["/velodyne_packets"].messages, 2u);
  EXPECT_EQ(t["/velodyne_packets"].type, kScan);
  EXPECT_EQ(t["/velodyne_packets"].encoding, "cdr");
  EXPECT_EQ(t["/points_be"].messages, 1u);
  EXPECT_EQ(t["/points_abs"].messages, 1u);
}

// ------------------------------------------------------------------ reading the fixtures

TEST_F(Ros2Bags, Db3FolderReadsSplitFilesInLogTimeOrder) {
  auto bag = open_bag(dir() / "ros2_db3");
  EXPECT_THAT(bag->describe(), HasSubstr("2 sqlite3 files"));
  expect_fixture_topics(*bag);
  EXPECT_EQ(topic_map(*bag).size(), 5u);
  expect_fixture_messages(read_all(*bag));
}

TEST_F(Ros2Bags, Db3FileAndMetadataPathOpenDirectly) {
  // The first split file alone: its rows are stored in reverse time order and come out sorted.
  auto part = open_bag(dir() / "ros2_db3" / "ros2_db3_0.db3");
  const auto msgs = read_all(*part);
  ASSERT_EQ(msgs.size(), 9u);  // 4 clouds, 2 scans, imu 0..2
  EXPECT_TRUE(std::is_sorted(msgs.begin(), msgs.end(),
                             [](const BagMessage& a, const BagMessage& b) { return a.log_time_ns < b.log_time_ns; }));
  EXPECT_EQ(topic_map(*part)["/velodyne_packets"].encoding, "cdr");  // stored empty, read as CDR
  auto via_yaml = open_bag(dir() / "ros2_db3" / "metadata.yaml");
  expect_fixture_messages(read_all(*via_yaml));
}

TEST_F(Ros2Bags, Db3WithZstdMessagesAndZstdFiles) {
  auto per_message = open_bag(dir() / "ros2_db3_msgzstd");
  expect_fixture_topics(*per_message);
  expect_fixture_messages(read_all(*per_message));
  auto per_file = open_bag(dir() / "ros2_db3_filezstd");
  expect_fixture_topics(*per_file);
  expect_fixture_messages(read_all(*per_file));
}

TEST_F(Ros2Bags, McapReadsUncompressedZstdAndLz4ChunksInLogTimeOrder) {
  auto bag = open_bag(dir() / "ros2.mcap");
  EXPECT_THAT(bag->describe(), HasSubstr("MCAP"));
  expect_fixture_topics(*bag);
  auto t = topic_map(*bag);
  EXPECT_EQ(t["/diagnostics_json"].encoding, "json");  // listed, its message skipped
  EXPECT_EQ(t["/diagnostics_json"].messages, 1u);
  EXPECT_EQ(t["/imu_ros1"].type, kImu);  // "sensor_msgs/Imu" in ROS 2 spelling
  EXPECT_EQ(t["/imu_ros1"].encoding, "ros1");
  const auto msgs = read_all(*bag);
  ASSERT_EQ(msgs.size(), 14u);
  EXPECT_TRUE(std::is_sorted(msgs.begin(), msgs.end(),
                             [](const BagMessage& a, const BagMessage& b) { return a.log_time_ns < b.log_time_ns; }));
  expect_fixture_messages(msgs);
  const auto ros1 = std::find_if(msgs.begin(), msgs.end(), [](const BagMessage& m) { return m.topic == "/imu_ros1"; });
  ASSERT_NE(ros1, msgs.end());
  EXPECT_EQ(ros1->serialization, Serialization::kRos1);
  EXPECT_EQ(ros1->log_time_ns, info()["ros2_mcap"]["imu_ros1_log_time"].get<int64_t>());
  expect_imu_values(decode_imu(*ros1), 1, /*with_covariances=*/false);
}

TEST_F(Ros2Bags, McapFolderWithMetadata) {
  auto bag = open_bag(dir() / "ros2_mcap");
  EXPECT_THAT(bag->describe(), HasSubstr("mcap"));
  expect_fixture_messages(read_all(*bag));
}

TEST_F(Ros2Bags, SmallMcapTopLevelMessageAndTwoChunks) {
  auto bag = open_bag(dir() / "small.mcap");
  const auto msgs = read_all(*bag);
  ASSERT_EQ(msgs.size(), 4u);
  const std::vector<std::pair<std::string, int64_t>> expected = {
      {"/velodyne_packets", 10}, {"/imu", 20}, {"/points", 30}, {"/imu", 40}};
  for (size_t i = 0; i < msgs.size(); ++i) {
    EXPECT_EQ(msgs[i].topic, expected[i].first);
    EXPECT_EQ(msgs[i].log_time_ns, expected[i].second);
  }
  expect_scan_k(msgs[0], 0);
  expect_imu_values(decode_imu(msgs[1]), 0);
  expect_cloud_k(msgs[2], 0);
  expect_imu_values(decode_imu(msgs[3]), 1);
}

// ------------------------------------------------------------------ cloud_points on hand-made clouds

PointCloud2Msg xyz_cloud(uint32_t n) {
  PointCloud2Msg c;
  c.header.stamp_ns = 5 * kNs;
  c.header.frame_id = "f";
  c.height = 1;
  c.width = n;
  c.fields = {{"x", 0, 7, 1}, {"y", 4, 7, 1}, {"z", 8, 7, 1}};
  c.point_step = 12;
  c.row_step = 12 * n;
  c.data.resize(c.row_step);
  for (uint32_t i = 0; i < n; ++i) {
    const float v[3] = {static_cast<float>(i), 2.0f, 3.0f};
    std::memcpy(c.data.data() + 12 * i, v, sizeof(v));
  }
  return c;
}

TEST(CloudPoints, AbsentTimeAndRingAreReportedNotInvented) {
  const DecodedCloud d = cloud_points(xyz_cloud(4));
  ASSERT_EQ(d.points.size(), 4u);
  EXPECT_FALSE(d.has_time);
  EXPECT_FALSE(d.has_ring);
  EXPECT_FALSE(d.has_intensity);
  EXPECT_TRUE(d.time_field.empty());
  EXPECT_EQ(d.points[3].x, 3.0f);
}

TEST(CloudPoints, OrganisedCloudUsesRowStep) {
  // 2 rows of 2 points with 4 bytes of padding at the end of each row.
  PointCloud2Msg c = xyz_cloud(4);
  c.height = 2;
  c.width = 2;
  c.row_step = 28;
  std::vector<uint8_t> data(56, 0);
  std::memcpy(data.data(), c.data.data(), 24);
  std::memcpy(data.data() + 28, c.data.data() + 24, 24);
  c.data = data;
  const DecodedCloud d = cloud_points(c);
  ASSERT_EQ(d.points.size(), 4u);
  for (int i = 0; i < 4; ++i) EXPECT_EQ(d.points[static_cast<size_t>(i)].x, static_cast<float>(i));
}

TEST(CloudPoints, FieldBeyondPointStepThrows) {
  PointCloud2Msg c = xyz_cloud(2);
  c.fields.push_back({"intensity", 10, 7, 1});  // bytes 10..13 of a 12-byte point
  const std::string what = format_error([&] { cloud_points(c); });
  EXPECT_THAT(what, HasSubstr("'intensity'"));
  EXPECT_THAT(what, HasSubstr("point_step 12"));
  EXPECT_THAT(what, HasSubstr("ends at byte 14"));
}

TEST(CloudPoints, DataShorterThanRowsThrows) {
  PointCloud2Msg c = xyz_cloud(3);
  c.data.resize(30);
  EXPECT_THAT(format_error([&] { cloud_points(c); }), HasSubstr("data holds 30 bytes"));
  PointCloud2Msg d = xyz_cloud(3);
  d.row_step = 20;
  EXPECT_THAT(format_error([&] { cloud_points(d); }), HasSubstr("row_step 20"));
}

TEST(CloudPoints, MissingOrIntegerXyzThrows) {
  PointCloud2Msg c = xyz_cloud(1);
  c.fields.pop_back();
  EXPECT_THAT(format_error([&] { cloud_points(c); }), HasSubstr("no field 'z'"));
  PointCloud2Msg d = xyz_cloud(1);
  d.fields[0].datatype = 5;  // INT32
  EXPECT_THAT(format_error([&] { cloud_points(d); }), HasSubstr("'x' has datatype INT32"));
}

// ------------------------------------------------------------------ bad input

TEST_F(Ros2Bags, DecodersRejectOtherTypes) {
  auto bag = open_bag(dir() / "small.mcap");
  const auto msgs = read_all(*bag);
  const BagMessage& imu = msgs[1];
  EXPECT_THAT(format_error([&] { decode_point_cloud2(imu); }), HasSubstr("has type 'sensor_msgs/msg/Imu'"));
  EXPECT_THAT(format_error([&] { decode_velodyne_scan(imu); }), HasSubstr("expected velodyne_msgs/msg/VelodyneScan"));
  BagMessage unknown = imu;
  unknown.type = "foo_msgs/msg/Bar";
  EXPECT_THAT(format_error([&] { decode_imu(unknown); }), HasSubstr("'foo_msgs/msg/Bar'"));
}

TEST_F(Ros2Bags, EveryTruncatedCdrMessageThrows) {
  auto bag = open_bag(dir() / "small.mcap");
  for (const BagMessage& full : read_all(*bag)) {
    for (size_t n = 0; n < full.data.size(); ++n) {
      BagMessage m = full;
      m.data.resize(n);
      const std::string what = format_error([&] {
        if (m.type == kPc2) decode_point_cloud2(m);
        if (m.type == kImu) decode_imu(m);
        if (m.type == kScan) decode_velodyne_scan(m);
      });
      ASSERT_THAT(what, HasSubstr(m.type)) << n;
      ASSERT_THAT(what, HasSubstr("byte offset")) << n;
    }
  }
}

TEST_F(Ros2Bags, SequenceLongerThanDataThrows) {
  auto bag = open_bag(dir() / "small.mcap");
  const auto msgs = read_all(*bag);
  // VelodyneScan: 4 (encapsulation) + 8 (stamp) + 4 + 9 ("velodyne\0") = 25, padded to 28: packet count.
  BagMessage scan = msgs[0];
  ASSERT_EQ(scan.data[28], 3);
  scan.data[28] = 4;
  std::string what = format_error([&] { decode_velodyne_scan(scan); });
  EXPECT_THAT(what, HasSubstr("'packets'"));
  EXPECT_THAT(what, HasSubstr("byte offset 28"));
  EXPECT_THAT(what, HasSubstr("4 elements"));
  // PointCloud2: the data length is the uint32 before the 240 data bytes and is_dense.
  BagMessage cloud = msgs[2];
  const size_t data_len_at = cloud.data.size() - 1 - 240 - 4;
  ASSERT_EQ(cloud.data[data_len_at], 240);
  cloud.data[data_len_at + 1] = 1;  // 240 + 256
  what = format_error([&] { decode_point_cloud2(cloud); });
  EXPECT_THAT(what, HasSubstr("'data'"));
  EXPECT_THAT(what, HasSubstr("byte offset " + std::to_string(data_len_at)));
  // A big-endian encapsulation kind that is not plain CDR.
  BagMessage xcdr2 = msgs[1];
  xcdr2.data[1] = 0x07;
  EXPECT_THAT(format_error([&] { decode_imu(xcdr2); }), HasSubstr("not plain CDR"));
}

TEST_F(Ros2Bags, McapTruncatedAtEveryLengthThrows) {
  const fs::path src = dir() / "small.mcap";
  const auto bytes = read_bytes(src);
  ASSERT_EQ(bytes.size(), info()["small_mcap"]["size"].get<size_t>());
  // Through open_bag on a file, at a stride (the file path must be named) ...
  const fs::path cut = dir() / "cut.mcap";
  for (size_t n = 0; n < bytes.size(); n += 97) {
    write_bytes(cut, bytes, n);
    const std::string what = format_error([&] { open_bag(cut); });
    ASSERT_THAT(what, HasSubstr(cut.string())) << n;
  }
  // ... and at every length in memory; with the closing magic put back, so that the records are
  // walked until the cut.
  const std::vector<uint8_t> magic(bytes.end() - 8, bytes.end());
  for (size_t n = 0; n < bytes.size() - magic.size(); ++n) {
    std::vector<uint8_t> prefix(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(n));
    const std::string what = format_error([&] { detail::open_mcap_bag_bytes(prefix, "cut"); });
    ASSERT_THAT(what, HasSubstr("cut: ")) << n;
    if (n >= 8) {
      prefix.insert(prefix.end(), magic.begin(), magic.end());
      const std::string what2 = format_error([&] {
        auto r = detail::open_mcap_bag_bytes(prefix, "cut");
        read_all(*r);
      });
      ASSERT_THAT(what2, HasSubstr("byte")) << n;
    }
  }
}

TEST_F(Ros2Bags, McapWithEveryByteChangedNeverCrashes) {
  const auto bytes = read_bytes(dir() / "small.mcap");
  size_t rejected = 0;
  for (size_t i = 0; i < bytes.size(); ++i) {
    std::vector<uint8_t> b = bytes;
    b[i] ^= 0xFF;
    try {
      auto r = detail::open_mcap_bag_bytes(b, "mutated");
      BagMessage m;
      while (r->next(m)) {
        if (m.type == kPc2) cloud_points(decode_point_cloud2(m));
        if (m.type == kImu) decode_imu(m);
        if (m.type == kScan) decode_velodyne_scan(m);
      }
    } catch (const FormatError&) {
      ++rejected;
    }
  }
  // Framing bytes, lengths and CRC-covered records must be caught; payload bytes may pass.
  EXPECT_GT(rejected, bytes.size() / 20);
}

TEST_F(Ros2Bags, McapBadChunkCrcNamesTheChunk) {
  const auto& s = info()["small_mcap"];
  const std::string what = format_error([&] { open_bag(dir() / "bad_crc.mcap"); });
  EXPECT_THAT(what, HasSubstr((dir() / "bad_crc.mcap").string()));
  EXPECT_THAT(what, HasSubstr("CRC mismatch"));
  EXPECT_THAT(what,
              HasSubstr("Chunk record (opcode 0x6) at byte " + std::to_string(s["chunk_offset"].get<uint64_t>())));
}

TEST_F(Ros2Bags, McapRecordLongerThanFileThrows) {
  auto bytes = read_bytes(dir() / "small.mcap");
  // The Header record at byte 8: its length field (bytes 9..16) made huge.
  bytes[16] = 0x40;
  const std::string what = format_error([&] { detail::open_mcap_bag_bytes(bytes, "long"); });
  EXPECT_THAT(what, HasSubstr("Header record (opcode 0x1) at byte 8 claims"));
}

TEST_F(Ros2Bags, TruncatedDb3Throws) {
  const fs::path src = dir() / "ros2_db3" / "ros2_db3_0.db3";
  const auto bytes = read_bytes(src);
  ASSERT_GT(bytes.size(), 8192u);
  const fs::path cut = dir() / "cut.db3";
  // Cut mid-page, and cut at a page boundary (the header's page count then disagrees).
  for (const size_t n : {bytes.size() - 1000, bytes.size() - 4096, size_t{4096}, size_t{50}}) {
    write_bytes(cut, bytes, n);
    const std::string what = format_error([&] {
      auto r = open_bag(cut);
      read_all(*r);
    });
    EXPECT_THAT(what, HasSubstr(cut.string())) << n;
    EXPECT_THAT(what, HasSubstr("truncated")) << n;
  }
}

TEST_F(Ros2Bags, NotABagAndMissingFilesThrow) {
  const fs::path text = dir() / "notes.txt";
  std::ofstream(text) << "hello, not a bag\n";
  EXPECT_THAT(format_error([&] { open_bag(text); }), HasSubstr(text.string() + ": not a bag"));
  EXPECT_THAT(format_error([&] { open_bag(dir() / "absent.mcap"); }), HasSubstr("no such file"));
  const fs::path folder = dir() / "broken_folder";
  fs::create_directories(folder);
  std::ofstream(folder / "metadata.yaml")
      << "rosbag2_bagfile_information:\n  storage_identifier: sqlite3\n  relative_file_paths:\n    - gone_0.db3\n";
  const std::string what = format_error([&] { open_bag(folder); });
  EXPECT_THAT(what, HasSubstr("gone_0.db3"));
  EXPECT_THAT(what, HasSubstr("metadata.yaml"));
  std::ofstream(folder / "metadata.yaml") << "rosbag2_bagfile_information: [\n";
  EXPECT_THAT(format_error([&] { open_bag(folder); }), HasSubstr("not valid YAML"));
}

TEST_F(Ros2Bags, Ros1MagicGoesToTheRos1Reader) {
  // A V2.0 version line with nothing valid after it: the ROS 1 reader rejects it, naming the file.
  const fs::path v20 = dir() / "damaged.bag";
  std::ofstream(v20, std::ios::binary) << "#ROSBAG V2.0\n" << std::string(20, '\0');
  EXPECT_THAT(format_error([&] {
                auto r = open_bag(v20);
                read_all(*r);
              }),
              HasSubstr(v20.string()));
  const fs::path v12 = dir() / "old.bag";
  std::ofstream(v12, std::ios::binary) << "#ROSBAG V1.2\n" << std::string(20, '\0');
  EXPECT_THAT(format_error([&] { open_bag(v12); }), HasSubstr("unsupported version"));
}

// ------------------------------------------------------------------ real Velodyne bags (nebula)

struct RealBag {
  const char* folder;  // under real/packets/velodyne/
  const char* topic;
  const char* frame;
  std::vector<int64_t> log_times;
  std::vector<double> header_stamps;  // [s], as SUMMARY.txt prints them (6 decimals)
  std::vector<size_t> packets;
  uint8_t return_mode, product_id;
};

fs::path data_dir() {
  const char* env = std::getenv("CDC_DATA_DIR");
  return env != nullptr && *env != '\0' ? fs::path(env) : fs::path("../shared/data");
}

class RealVelodyneBag : public ::testing::TestWithParam<RealBag> {};

TEST_P(RealVelodyneBag, MatchesSummary) {
  const RealBag& e = GetParam();
  const fs::path folder = data_dir() / "real/packets/velodyne" / e.folder;
  if (!fs::exists(folder)) GTEST_SKIP() << "reference data absent: " << folder;
  auto bag = open_bag(folder);
  const auto topics = bag->topics();
  ASSERT_EQ(topics.size(), 1u);
  EXPECT_EQ(topics[0].name, e.topic);
  EXPECT_EQ(topics[0].type, kScan);
  EXPECT_EQ(topics[0].encoding, "cdr");
  EXPECT_EQ(topics[0].messages, e.log_times.size());
  const auto msgs = read_all(*bag);
  ASSERT_EQ(msgs.size(), e.log_times.size());
  size_t total = 0;
  for (size_t i = 0; i < msgs.size(); ++i) {
    SCOPED_TRACE("message " + std::to_string(i));
    EXPECT_EQ(msgs[i].topic, e.topic);
    EXPECT_EQ(msgs[i].log_time_ns, e.log_times[i]);
    const VelodyneScanMsg scan = decode_velodyne_scan(msgs[i]);
    EXPECT_EQ(scan.header.frame_id, e.frame);
    EXPECT_NEAR(static_cast<double>(scan.header.stamp_ns - static_cast<int64_t>(e.header_stamps[i]) * kNs) * 1e-9,
                e.header_stamps[i] - std::floor(e.header_stamps[i]), 1e-6);
    ASSERT_EQ(scan.packets.size(), e.packets[i]);
    total += scan.packets.size();
    for (size_t p = 0; p < scan.packets.size(); ++p) {
      const auto& d = scan.packets[p].data;
      ASSERT_EQ(d[0], 0xff) << "packet " << p;  // first block flag 0xeeff
      ASSERT_EQ(d[1], 0xee) << "packet " << p;
      ASSERT_EQ(d[1204], e.return_mode) << "packet " << p;
      ASSERT_EQ(d[1205], e.product_id) << "packet " << p;
    }
  }
  size_t expected_total = 0;
  for (size_t n : e.packets) expected_total += n;
  EXPECT_EQ(total, expected_total);
}

INSTANTIATE_TEST_SUITE_P(
    Nebula, RealVelodyneBag,
    ::testing::Values(RealBag{"vlp16/1673400471837873222",
                              "/velodyne_packets",
                              "velodyne",
                              {1673400471837873222, 1673400471937957440, 1673400472038371929, 1673400472138016708},
                              {1673400471.737763, 1673400471.837961, 1673400471.938157, 1673400472.038354},
                              {151, 151, 151, 150},
                              0x39,
                              0x22},
                      RealBag{"vlp32/1713492677464078412",
                              "/sensing/lidar/front/velodyne_packets",
                              "velodyne_front",
                              {1713492677464078412, 1713492677545368298, 1713492677630748420, 1713492677730768896,
                               1713492677841065510},
                              {1713492677.327772, 1713492677.427865, 1713492677.528578, 1713492677.628081,
                               1713492677.727441},
                              {76, 76, 76, 75, 76},
                              0x37,
                              0x28},
                      RealBag{"vls128/1614315746471294674",
                              "/velodyne_packets",
                              "velodyne_top",
                              {1585897255313147068, 1585897255376374245, 1585897255476339817, 1585897255576312065},
                              {1585897255.313147, 1585897255.376374, 1585897255.476340, 1585897255.576312},
                              {383, 603, 603, 604},
                              0x37,
                              0xa1}),
    [](const ::testing::TestParamInfo<RealBag>& i) {
      return std::string(i.param.folder).substr(0, std::string(i.param.folder).find('/'));
    });

TEST(RealVelodyneBagDamage, TruncatedCopyThrows) {
  const fs::path src = data_dir() / "real/packets/velodyne/vlp16/1673400471837873222/1673400471837873222_0.db3";
  if (!fs::exists(src)) GTEST_SKIP() << "reference data absent: " << src;
  const auto bytes = read_bytes(src);
  const fs::path cut = fs::temp_directory_path() / ("cdc_ros2_cut_vlp16_" + std::to_string(::getpid()) + ".db3");
  for (const size_t n : {bytes.size() / 2, bytes.size() / 2 + 123}) {
    write_bytes(cut, bytes, n);
    const std::string what = format_error([&] {
      auto r = open_bag(cut);
      read_all(*r);
    });
    EXPECT_THAT(what, HasSubstr(cut.string()));
    EXPECT_THAT(what, HasSubstr("truncated"));
  }
  fs::remove(cut);
}

}  // namespace
}  // namespace cdc::io
