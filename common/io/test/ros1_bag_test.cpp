// ROS 1 bag reading and ROS 1 message decoding, checked against bags written by python3-rosbag
// (make_ros1_fixtures.py: genpy serialises the messages, rosbag writes chunks, indexes and the
// bz2/lz4 compression), plus damaged copies of them.

#include "ros1_bag.hpp"
#include "ros1_messages.hpp"

#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace cdc::io {
namespace {

namespace fs = std::filesystem;

constexpr int64_t kSecond = 1'000'000'000;

// One message as the fixture script wrote it (manifest.txt).
struct Written {
  std::string topic;
  int index = 0;
  int64_t time_ns = 0;
};

// The fixture bags, written once per test program into a temporary folder.
class Fixtures {
 public:
  Fixtures() : dir_(fs::temp_directory_path() / ("cdc_ros1_bag_test_" + std::to_string(getpid()))) {
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    const std::string command =
        std::string("'") + CDC_PYTHON3 + "' '" + CDC_ROS1_FIXTURE_SCRIPT + "' '" + dir_.string() + "' 2>&1";
    FILE* pipe = popen(command.c_str(), "r");
    if (pipe == nullptr) {
      error_ = "cannot run " + command;
      return;
    }
    std::array<char, 512> buf{};
    while (fgets(buf.data(), static_cast<int>(buf.size()), pipe) != nullptr) output_ += buf.data();
    if (pclose(pipe) != 0) {
      error_ = command + " failed (python3-rosbag installed?):\n" + output_;
      return;
    }
    std::ifstream manifest(dir_ / "manifest.txt");
    std::string bag;
    Written w;
    int64_t sec = 0, nsec = 0;
    while (manifest >> bag >> w.topic >> w.index >> sec >> nsec) {
      w.time_ns = sec * kSecond + nsec;
      written_[bag].push_back(w);
    }
    if (written_.empty()) error_ = "the fixture script wrote no manifest:\n" + output_;
  }
  ~Fixtures() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  Fixtures(const Fixtures&) = delete;
  Fixtures& operator=(const Fixtures&) = delete;

  const std::string& error() const { return error_; }
  fs::path path(const std::string& bag) const { return dir_ / bag; }
  const fs::path& dir() const { return dir_; }
  // In write (= file) order.
  const std::vector<Written>& written(const std::string& bag) const { return written_.at(bag); }

 private:
  fs::path dir_;
  std::string output_;
  std::string error_;
  std::map<std::string, std::vector<Written>> written_;
};

const Fixtures& fixtures() {
  static const Fixtures f;
  return f;
}

std::vector<Written> in_time_order(std::vector<Written> w) {
  std::stable_sort(w.begin(), w.end(), [](const Written& a, const Written& b) { return a.time_ns < b.time_ns; });
  return w;
}

std::vector<BagMessage> read_all(BagReader& reader) {
  std::vector<BagMessage> out;
  BagMessage m;
  while (reader.next(m)) out.push_back(m);
  return out;
}

std::vector<uint8_t> file_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// Offset of the first occurrence of `needle` at or after `from`, or npos.
size_t find_bytes(const std::vector<uint8_t>& hay, std::string_view needle, size_t from) {
  const auto it = std::search(hay.begin() + static_cast<std::ptrdiff_t>(from), hay.end(), needle.begin(), needle.end());
  return it == hay.end() ? std::string::npos : static_cast<size_t>(it - hay.begin());
}

float float_at(const std::vector<uint8_t>& data, size_t offset) {
  float v = 0;
  std::memcpy(&v, data.data() + offset, sizeof v);
  return v;
}

// The values make_ros1_fixtures.py gives message i of each topic.
void expect_imu(const ImuMsg& m, int i) {
  EXPECT_EQ(m.header.stamp_ns, (1000 + i) * kSecond + 1000 * i + 7);
  EXPECT_EQ(m.header.frame_id, "imu_link");
  EXPECT_EQ(m.orientation.x(), 0.125 * i);
  EXPECT_EQ(m.orientation.y(), -0.25);
  EXPECT_EQ(m.orientation.z(), 0.5);
  EXPECT_EQ(m.orientation.w(), 0.75);
  EXPECT_EQ(m.angular_velocity, Eigen::Vector3d(0.5 * i, -1.5, 2.25));
  EXPECT_EQ(m.linear_acceleration, Eigen::Vector3d(i + 0.125, -9.75, 3.5));
}

void expect_cloud(const PointCloud2Msg& m, int i) {
  const uint32_t width = 3 + static_cast<uint32_t>(i % 4);
  EXPECT_EQ(m.header.stamp_ns, (2000 + i) * kSecond + 500);
  EXPECT_EQ(m.header.frame_id, "velodyne");
  EXPECT_EQ(m.height, 1u);
  EXPECT_EQ(m.width, width);
  const std::vector<std::pair<std::string, uint8_t>> fields = {{"x", 7},         {"y", 7},    {"z", 7},
                                                               {"intensity", 7}, {"ring", 4}, {"time", 7}};
  const std::vector<uint32_t> offsets = {0, 4, 8, 12, 16, 18};
  ASSERT_EQ(m.fields.size(), fields.size());
  for (size_t f = 0; f < fields.size(); ++f) {
    EXPECT_EQ(m.fields[f].name, fields[f].first);
    EXPECT_EQ(m.fields[f].datatype, fields[f].second);
    EXPECT_EQ(m.fields[f].offset, offsets[f]);
    EXPECT_EQ(m.fields[f].count, 1u);
  }
  EXPECT_FALSE(m.is_bigendian);
  EXPECT_EQ(m.point_step, 22u);
  EXPECT_EQ(m.row_step, 22u * width);
  EXPECT_EQ(m.is_dense, i % 2 == 0);
  ASSERT_EQ(m.data.size(), 22u * width);
  for (uint32_t j = 0; j < width; ++j) {
    const size_t p = 22u * j;
    const auto fj = static_cast<float>(j);
    EXPECT_EQ(float_at(m.data, p + 0), static_cast<float>(i) + 0.25f * fj);
    EXPECT_EQ(float_at(m.data, p + 4), -0.5f * fj);
    EXPECT_EQ(float_at(m.data, p + 8), 1.5f);
    EXPECT_EQ(float_at(m.data, p + 12), 10.0f * fj);
    EXPECT_EQ(m.data[p + 16] | (m.data[p + 17] << 8), static_cast<int>(j));
    EXPECT_EQ(float_at(m.data, p + 18), 0.001953125f * fj);
  }
}

void expect_scan(const VelodyneScanMsg& m, int i) {
  EXPECT_EQ(m.header.stamp_ns, (3000 + i) * kSecond);
  EXPECT_EQ(m.header.frame_id, "velodyne");
  ASSERT_EQ(m.packets.size(), 2u);
  for (int k = 0; k < 2; ++k) {
    const VelodynePacketMsg& p = m.packets[static_cast<size_t>(k)];
    EXPECT_EQ(p.stamp_ns, (3000 + i) * kSecond + 1000 * k + 1);
    for (size_t b = 0; b < p.data.size(); ++b) {
      ASSERT_EQ(p.data[b], static_cast<uint8_t>((static_cast<int>(b) + 7 * k + 13 * i) % 256))
          << "scan " << i << " packet " << k << " byte " << b;
    }
  }
}

void expect_message(const BagMessage& m, const Written& w) {
  SCOPED_TRACE(w.topic + " #" + std::to_string(w.index));
  EXPECT_EQ(m.topic, w.topic);
  EXPECT_EQ(m.log_time_ns, w.time_ns);
  EXPECT_EQ(m.serialization, Serialization::kRos1);
  if (w.topic == "/imu") {
    EXPECT_EQ(m.type, "sensor_msgs/msg/Imu");
    expect_imu(decode_imu_ros1(m), w.index);
  } else if (w.topic == "/points") {
    EXPECT_EQ(m.type, "sensor_msgs/msg/PointCloud2");
    expect_cloud(decode_point_cloud2_ros1(m), w.index);
  } else {
    EXPECT_EQ(m.type, "velodyne_msgs/msg/VelodyneScan");
    expect_scan(decode_velodyne_scan_ros1(m), w.index);
  }
}

class Ros1BagTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(fixtures().error().empty()) << fixtures().error(); }
};

class Ros1CompressionTest : public Ros1BagTest, public ::testing::WithParamInterface<std::string> {};

TEST_P(Ros1CompressionTest, YieldsEveryMessageInTimeOrderAcrossChunks) {
  const std::string name = "mixed_" + GetParam() + ".bag";
  const std::vector<Written> expected = in_time_order(fixtures().written(name));
  // The clouds are written late, so chunks overlap in time and file order is not time order.
  bool file_order_differs = false;
  for (size_t k = 0; k < expected.size(); ++k) {
    file_order_differs |= fixtures().written(name)[k].time_ns != expected[k].time_ns;
  }
  ASSERT_TRUE(file_order_differs);

  const auto reader = open_ros1_bag(fixtures().path(name));
  EXPECT_NE(reader->describe().find(name), std::string::npos);
  const std::vector<BagTopic> topics = reader->topics();
  ASSERT_EQ(topics.size(), 3u);
  EXPECT_EQ(topics[0].name, "/imu");
  EXPECT_EQ(topics[0].type, "sensor_msgs/msg/Imu");
  EXPECT_EQ(topics[1].name, "/points");
  EXPECT_EQ(topics[1].type, "sensor_msgs/msg/PointCloud2");
  EXPECT_EQ(topics[2].name, "/velodyne_packets");
  EXPECT_EQ(topics[2].type, "velodyne_msgs/msg/VelodyneScan");
  for (const BagTopic& t : topics) {
    EXPECT_EQ(t.messages, 20u) << t.name;
    EXPECT_EQ(t.encoding, "ros1") << t.name;
  }

  const std::vector<BagMessage> messages = read_all(*reader);
  ASSERT_EQ(messages.size(), expected.size());
  for (size_t k = 0; k < messages.size(); ++k) expect_message(messages[k], expected[k]);
  BagMessage m;
  EXPECT_FALSE(reader->next(m));  // the end stays the end
}

INSTANTIATE_TEST_SUITE_P(Compressions, Ros1CompressionTest, ::testing::Values("none", "bz2", "lz4"));

TEST_F(Ros1BagTest, CompressedChunksHoldTheSameBytesAsUncompressed) {
  const auto plain = open_ros1_bag(fixtures().path("mixed_none.bag"));
  const std::vector<BagMessage> expected = read_all(*plain);
  for (const std::string name : {"mixed_bz2.bag", "mixed_lz4.bag"}) {
    const auto reader = open_ros1_bag(fixtures().path(name));
    const std::vector<BagMessage> got = read_all(*reader);
    ASSERT_EQ(got.size(), expected.size()) << name;
    for (size_t k = 0; k < got.size(); ++k) EXPECT_EQ(got[k].data, expected[k].data) << name << " #" << k;
  }
}

// A recording that was not closed has no index section; its chunks are scanned.
TEST_F(Ros1BagTest, ReadsBagsThatWereNotClosed) {
  for (const std::string name : {"unclosed_between_chunks.bag", "unclosed_in_chunk.bag"}) {
    SCOPED_TRACE(name);
    const std::vector<Written> expected = in_time_order(fixtures().written(name));
    const auto reader = open_ros1_bag(fixtures().path(name));
    const std::vector<BagMessage> messages = read_all(*reader);
    ASSERT_EQ(messages.size(), expected.size());
    for (size_t k = 0; k < messages.size(); ++k) expect_message(messages[k], expected[k]);
    uint64_t counted = 0;
    for (const BagTopic& t : reader->topics()) counted += t.messages;
    EXPECT_EQ(counted, expected.size());
  }
}

class Ros1TruncationTest : public Ros1BagTest, public ::testing::WithParamInterface<std::string> {};

// Every proper prefix of a closed bag is damaged: reading it yields messages of intact chunks (in
// the bag's time order, each byte for byte as in the whole bag) and then throws FormatError, or
// opening it throws. It never ends cleanly, never yields other data, never crashes, and a longer
// prefix never yields fewer messages (a chunk whose index records are cut short is still read).
TEST_P(Ros1TruncationTest, EveryTruncationYieldsAnIntactPrefixThenThrows) {
  const fs::path source = fixtures().path("small_" + GetParam() + ".bag");
  const auto whole = open_ros1_bag(source);
  const std::vector<BagMessage> all = read_all(*whole);
  ASSERT_EQ(all.size(), 5u);  // two chunks, each with messages on /imu and /points

  const fs::path cut = fixtures().dir() / ("truncated_" + GetParam() + ".bag");
  fs::copy_file(source, cut, fs::copy_options::overwrite_existing);
  const uint64_t size = fs::file_size(source);
  size_t thrown_at_open = 0, yielded_some = 0;
  size_t yielded_by_longer = all.size();  // by the previous (one byte longer) prefix
  for (uint64_t len = size; len-- > 0;) {
    fs::resize_file(cut, len);
    SCOPED_TRACE("truncated to " + std::to_string(len) + " of " + std::to_string(size) + " bytes");
    std::unique_ptr<BagReader> reader;
    try {
      reader = open_ros1_bag(cut);
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find(cut.string()), std::string::npos) << e.what();
      ++thrown_at_open;
      yielded_by_longer = 0;
      continue;
    }
    size_t k = 0;
    bool threw = false;
    try {
      BagMessage m;
      while (reader->next(m)) {
        ASSERT_LT(k, all.size());
        EXPECT_EQ(m.topic, all[k].topic);
        EXPECT_EQ(m.type, all[k].type);
        EXPECT_EQ(m.log_time_ns, all[k].log_time_ns);
        ASSERT_EQ(m.data, all[k].data);
        ++k;
      }
    } catch (const FormatError& e) {
      threw = true;
      EXPECT_NE(std::string(e.what()).find(cut.string() + ": "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("byte "), std::string::npos) << e.what();
    }
    ASSERT_TRUE(threw) << "a truncated bag ended cleanly after " << k << " messages";
    BagMessage again;
    EXPECT_THROW(reader->next(again), FormatError);  // the failure is sticky
    EXPECT_LE(k, yielded_by_longer) << "a longer prefix yielded fewer messages";
    yielded_by_longer = k;
    if (k > 0) ++yielded_some;
    if (len == size - 1) {
      EXPECT_EQ(k, all.size()) << "only the index was cut: every chunk is intact";
    }
  }
  // Cuts inside the version line and bag header throw at open; later cuts keep earlier chunks.
  EXPECT_GT(thrown_at_open, 4000u);
  EXPECT_GT(yielded_some, 0u);
}

INSTANTIATE_TEST_SUITE_P(Compressions, Ros1TruncationTest, ::testing::Values("none", "lz4"));

// The FormatError's message that opening the bag and reading its first message raise; none when
// they succeed.
std::optional<std::string> first_read_error(const fs::path& path) {
  try {
    const auto reader = open_ros1_bag(path);
    BagMessage m;
    reader->next(m);
  } catch (const FormatError& e) {
    return std::string(e.what());
  }
  return std::nullopt;
}

TEST_F(Ros1BagTest, CorruptBz2ChunkThrows) {
  std::vector<uint8_t> bytes = file_bytes(fixtures().path("mixed_bz2.bag"));
  const size_t stream = find_bytes(bytes, "BZh9", 4096);
  ASSERT_NE(stream, std::string::npos);
  for (size_t k = 100; k < 110; ++k) bytes[stream + k] ^= 0x5A;
  const fs::path path = fixtures().dir() / "corrupt_bz2.bag";
  write_bytes(path, bytes);
  // The first chunk holds the earliest message, so no message comes before the error.
  const std::optional<std::string> what = first_read_error(path);
  ASSERT_TRUE(what) << "a corrupt bz2 chunk was read";
  EXPECT_NE(what->find(path.string() + ": byte "), std::string::npos) << *what;
  EXPECT_NE(what->find("bz2"), std::string::npos) << *what;
}

TEST_F(Ros1BagTest, RecordHeaderWithoutOpThrows) {
  std::vector<uint8_t> bytes = file_bytes(fixtures().path("mixed_none.bag"));
  // The first chunk record's header starts with its 'op' field: rename it to 'xp'.
  const size_t op = find_bytes(bytes, std::string_view("op=\x05", 4), 13);
  ASSERT_NE(op, std::string::npos);
  bytes[op] = 'x';
  const fs::path path = fixtures().dir() / "no_op.bag";
  write_bytes(path, bytes);
  const size_t record = op - 8;  // uint32 header length, uint32 field length
  const std::optional<std::string> what = first_read_error(path);
  ASSERT_TRUE(what) << "a record without 'op' was read";
  EXPECT_EQ(*what, path.string() + ": byte " + std::to_string(record) + ": record header has no 'op' field");
}

// Damage anywhere (seeded random byte changes) ends in FormatError or, where the change hits message
// payload that no check covers, in a clean read; never another exception or a crash.
TEST_F(Ros1BagTest, RandomlyDamagedBagsThrowOnlyFormatError) {
  std::mt19937 rng(7);
  for (const std::string name : {"mixed_none.bag", "mixed_bz2.bag", "mixed_lz4.bag"}) {
    const std::vector<uint8_t> original = file_bytes(fixtures().path(name));
    std::uniform_int_distribution<size_t> position(0, original.size() - 1);
    std::uniform_int_distribution<int> value(0, 255);
    const fs::path path = fixtures().dir() / ("damaged_" + name);
    size_t format_errors = 0;
    for (int trial = 0; trial < 60; ++trial) {
      std::vector<uint8_t> bytes = original;
      for (int k = 0; k < 3; ++k) bytes[position(rng)] = static_cast<uint8_t>(value(rng));
      write_bytes(path, bytes);
      try {
        const auto reader = open_ros1_bag(path);
        read_all(*reader);
      } catch (const FormatError&) {
        ++format_errors;
      } catch (const std::exception& e) {
        ADD_FAILURE() << name << " trial " << trial << ": " << e.what();
      }
    }
    EXPECT_GT(format_errors, 0u) << name;
  }
}

TEST_F(Ros1BagTest, NotABagThrowsAtOpen) {
  const fs::path path = fixtures().dir() / "not_a_bag.bag";
  write_bytes(path, std::vector<uint8_t>{'#', 'R', 'O', 'S', 'B', 'A', 'G', ' ', 'V', '1', '.', '2', '\n'});
  EXPECT_THROW(open_ros1_bag(path), FormatError);
  EXPECT_THROW(open_ros1_bag(fixtures().dir() / "missing.bag"), FormatError);
}

BagMessage first_message(const std::string& bag, const std::string& topic) {
  const auto reader = open_ros1_bag(fixtures().path(bag));
  BagMessage m;
  while (reader->next(m)) {
    if (m.topic == topic) return m;
  }
  ADD_FAILURE() << "no message on " << topic << " in " << bag;
  return m;
}

TEST_F(Ros1BagTest, DecodersRejectOtherTypes) {
  const BagMessage imu = first_message("mixed_none.bag", "/imu");
  EXPECT_NO_THROW(decode_imu_ros1(imu));
  EXPECT_THROW(decode_point_cloud2_ros1(imu), FormatError);
  EXPECT_THROW(decode_velodyne_scan_ros1(imu), FormatError);
  BagMessage other = imu;
  other.type = "std_msgs/msg/String";
  try {
    decode_imu_ros1(other);
    FAIL() << "an std_msgs/msg/String was decoded as Imu";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("std_msgs/msg/String"), std::string::npos) << e.what();
  }
  BagMessage cdr = imu;
  cdr.serialization = Serialization::kCdr;
  EXPECT_THROW(decode_imu_ros1(cdr), FormatError);
}

TEST_F(Ros1BagTest, CloudWhoseDataDisagreeWithRowStepThrows) {
  const BagMessage m = first_message("bad_cloud.bag", "/points");
  ASSERT_EQ(m.type, "sensor_msgs/msg/PointCloud2");
  try {
    decode_point_cloud2_ros1(m);
    FAIL() << "a cloud with 65 data bytes and row_step * height = 66 was decoded";
  } catch (const FormatError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/points"), std::string::npos) << what;
    EXPECT_NE(what.find("data holds 65 bytes, row_step * height = 66 * 1 = 66"), std::string::npos) << what;
  }
}

// Every truncation of a message and a trailing byte are errors naming the field and the offset.
TEST_F(Ros1BagTest, DecodersRejectTruncatedAndOverlongMessages) {
  const std::vector<std::pair<std::string, void (*)(const BagMessage&)>> cases = {
      {"/imu", [](const BagMessage& m) { decode_imu_ros1(m); }},
      {"/points", [](const BagMessage& m) { decode_point_cloud2_ros1(m); }},
      {"/velodyne_packets", [](const BagMessage& m) { decode_velodyne_scan_ros1(m); }},
  };
  for (const auto& [topic, decode] : cases) {
    const BagMessage whole = first_message("mixed_none.bag", topic);
    EXPECT_NO_THROW(decode(whole)) << topic;
    for (size_t len = 0; len < whole.data.size(); ++len) {
      BagMessage cut = whole;
      cut.data.resize(len);
      try {
        decode(cut);
        ADD_FAILURE() << topic << " truncated to " << len << " bytes was decoded";
      } catch (const FormatError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find(topic), std::string::npos) << what;
        EXPECT_NE(what.find("field '"), std::string::npos) << what;
        EXPECT_NE(what.find("at byte "), std::string::npos) << what;
      }
    }
    BagMessage longer = whole;
    longer.data.push_back(0);
    EXPECT_THROW(decode(longer), FormatError) << topic;
  }
}

TEST_F(Ros1BagTest, FieldErrorNamesFieldAndOffset) {
  BagMessage scan = first_message("mixed_none.bag", "/velodyne_packets");
  // header: seq (4) stamp (8) frame_id (4 + 8 "velodyne") -> packets length at byte 24.
  ASSERT_GE(scan.data.size(), 28u);
  scan.data[24] = 3;  // three packets, two present
  try {
    decode_velodyne_scan_ros1(scan);
    FAIL() << "a scan declaring three packets with two present was decoded";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("field 'packets' at byte 24 declares 3 elements"), std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace cdc::io
