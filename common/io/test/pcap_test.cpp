// pcap captures: what PcapWriter writes, libpcap (through PcapReader) reads back; Linux cooked and
// microsecond files built by hand; IPv4 fragments; damaged files.
#include "cdc/io/pcap.hpp"

#include "cdc/io/error.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

namespace cdc::io {
namespace {

class TempDir {
 public:
  TempDir() {
    path_ = std::filesystem::temp_directory_path() /
            ("cdc_pcap_test_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

std::vector<uint8_t> read_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void write_bytes(const std::filesystem::path& p, const std::vector<uint8_t>& b) {
  std::ofstream(p, std::ios::binary)
      .write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
}
uint32_t le32(const std::vector<uint8_t>& b, std::size_t at) {
  return static_cast<uint32_t>(b[at]) | (static_cast<uint32_t>(b[at + 1]) << 8) |
         (static_cast<uint32_t>(b[at + 2]) << 16) | (static_cast<uint32_t>(b[at + 3]) << 24);
}
void put_le32(std::vector<uint8_t>& b, uint32_t v) {
  for (int i = 0; i < 4; ++i) b.push_back(static_cast<uint8_t>(v >> (8 * i)));
}

// The records of a file PcapWriter wrote: {offset of the record header, captured length}.
std::vector<std::pair<std::size_t, std::size_t>> records_of(const std::vector<uint8_t>& file) {
  std::vector<std::pair<std::size_t, std::size_t>> out;
  for (std::size_t at = 24; at + 16 <= file.size();) {
    const std::size_t len = le32(file, at + 8);
    out.emplace_back(at, len);
    at += 16 + len;
  }
  return out;
}

UdpDatagram velodyne_datagram(int i, std::mt19937& rng) {
  UdpDatagram d;
  d.stamp_ns = 1'700'000'000'123'456'789 + static_cast<int64_t>(i) * 1'327'000;
  d.src_ip = 0x7F000001;
  d.dst_ip = 0x7F000001;
  d.src_port = 2368;
  d.dst_port = 2368;
  d.payload.resize(1206);
  for (auto& b : d.payload) b = static_cast<uint8_t>(rng());
  d.payload[0] = 0xFF;
  d.payload[1] = 0xEE;
  return d;
}

TEST(Pcap, WritesAndReadsVelodyneDatagrams) {
  TempDir t;
  std::mt19937 rng(7);
  std::vector<UdpDatagram> sent;
  {
    PcapWriter w(t / "a.pcap");
    for (int i = 0; i < 50; ++i) {
      sent.push_back(velodyne_datagram(i, rng));
      w.write(sent.back());
    }
    w.close();
    EXPECT_EQ(w.records(), 50u);
  }
  PcapReader r(t / "a.pcap");
  EXPECT_EQ(r.link_type(), 1);
  UdpDatagram d;
  std::size_t n = 0;
  while (r.next(d)) {
    ASSERT_LT(n, sent.size());
    EXPECT_EQ(d.stamp_ns, sent[n].stamp_ns);  // nanosecond file
    EXPECT_EQ(d.src_ip, 0x7F000001u);
    EXPECT_EQ(d.dst_port, 2368);
    EXPECT_EQ(d.src_port, 2368);
    EXPECT_EQ(d.payload, sent[n].payload);
    EXPECT_EQ(d.record, n);
    ++n;
  }
  EXPECT_EQ(n, sent.size());
  EXPECT_EQ(r.stats().records, 50u);
  EXPECT_EQ(r.stats().datagrams, 50u);
  EXPECT_EQ(r.stats().malformed + r.stats().skipped + r.stats().snapped, 0u);
}

TEST(Pcap, ReassemblesFragmentsAndCountsIncompleteOnes) {
  TempDir t;
  std::mt19937 rng(8);
  std::vector<UdpDatagram> sent;
  {
    PcapWriter w(t / "frag.pcap", 576);  // 1214-byte UDP datagrams -> 3 fragments each
    for (int i = 0; i < 4; ++i) {
      sent.push_back(velodyne_datagram(i, rng));
      w.write(sent.back());
    }
    EXPECT_EQ(w.records(), 12u);
  }
  {
    PcapReader r(t / "frag.pcap");
    UdpDatagram d;
    std::size_t n = 0;
    while (r.next(d)) EXPECT_EQ(d.payload, sent[n++].payload);
    EXPECT_EQ(n, 4u);
    EXPECT_EQ(r.stats().fragments, 12u);
    EXPECT_EQ(r.stats().reassembled, 4u);
    EXPECT_EQ(r.stats().incomplete_fragments, 0u);
  }
  // Drop the middle fragment of datagram 1 and swap the first two fragments of datagram 2.
  auto file = read_bytes(t / "frag.pcap");
  const auto recs = records_of(file);
  ASSERT_EQ(recs.size(), 12u);
  auto bytes_of = [&](std::size_t k) {
    return std::vector<uint8_t>(file.begin() + static_cast<std::ptrdiff_t>(recs[k].first),
                                file.begin() + static_cast<std::ptrdiff_t>(recs[k].first + 16 + recs[k].second));
  };
  std::vector<uint8_t> edited(file.begin(), file.begin() + 24);
  for (std::size_t k : {0u, 1u, 2u, 3u, 5u, 7u, 6u, 8u, 9u, 10u, 11u}) {
    const auto b = bytes_of(k);
    edited.insert(edited.end(), b.begin(), b.end());
  }
  write_bytes(t / "edited.pcap", edited);
  PcapReader r(t / "edited.pcap");
  UdpDatagram d;
  std::vector<std::vector<uint8_t>> got;
  while (r.next(d)) got.push_back(d.payload);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0], sent[0].payload);
  EXPECT_EQ(got[1], sent[2].payload);
  EXPECT_EQ(got[2], sent[3].payload);
  EXPECT_EQ(r.stats().incomplete_fragments, 2u);  // datagram 1's two fragments that arrived
}

TEST(Pcap, ReadsLinuxCookedAndMicrosecondFiles) {
  TempDir t;
  std::mt19937 rng(9);
  const UdpDatagram sent = velodyne_datagram(3, rng);
  {
    PcapWriter w(t / "eth.pcap");
    w.write(sent);
  }
  const auto eth = read_bytes(t / "eth.pcap");
  const auto rec = records_of(eth).at(0);
  const std::vector<uint8_t> ip(eth.begin() + static_cast<std::ptrdiff_t>(rec.first + 16 + 14),
                                eth.begin() + static_cast<std::ptrdiff_t>(rec.first + 16 + rec.second));
  // Linux cooked (SLL, link type 113), microsecond stamps (magic a1b2c3d4).
  std::vector<uint8_t> f;
  for (uint32_t w : {0xA1B2C3D4u, 0x00040002u, 0u, 0u, 65535u, 113u}) put_le32(f, w);
  std::vector<uint8_t> frame = {0, 0, 0, 1, 0, 6, 2, 0, 0, 0, 0, 1, 0, 0, 0x08, 0x00};
  frame.insert(frame.end(), ip.begin(), ip.end());
  put_le32(f, static_cast<uint32_t>(sent.stamp_ns / 1000000000));
  put_le32(f, static_cast<uint32_t>(sent.stamp_ns % 1000000000 / 1000));
  put_le32(f, static_cast<uint32_t>(frame.size()));
  put_le32(f, static_cast<uint32_t>(frame.size()));
  f.insert(f.end(), frame.begin(), frame.end());
  // An ARP frame's worth of SLL with another protocol: skipped.
  const std::vector<uint8_t> arp = {0, 0, 0, 1, 0, 6, 2, 0, 0, 0, 0, 1, 0, 0, 0x08, 0x06, 1, 2, 3, 4};
  for (uint32_t w : {1u, 0u, static_cast<uint32_t>(arp.size()), static_cast<uint32_t>(arp.size())}) put_le32(f, w);
  f.insert(f.end(), arp.begin(), arp.end());
  write_bytes(t / "sll.pcap", f);
  PcapReader r(t / "sll.pcap");
  EXPECT_EQ(r.link_type(), 113);
  UdpDatagram d;
  ASSERT_TRUE(r.next(d));
  EXPECT_EQ(d.payload, sent.payload);
  EXPECT_EQ(d.stamp_ns, sent.stamp_ns / 1000 * 1000);  // microseconds in the file
  EXPECT_FALSE(r.next(d));
  EXPECT_EQ(r.stats().skipped, 1u);
}

TEST(Pcap, DamagedFilesNameTheFileAndRecord) {
  TempDir t;
  std::mt19937 rng(10);
  {
    PcapWriter w(t / "full.pcap");
    for (int i = 0; i < 5; ++i) w.write(velodyne_datagram(i, rng));
  }
  auto file = read_bytes(t / "full.pcap");
  file.resize(file.size() - 600);  // the last record is cut short
  write_bytes(t / "cut.pcap", file);
  PcapReader r(t / "cut.pcap");
  UdpDatagram d;
  int n = 0;
  std::string error;
  try {
    while (r.next(d)) ++n;
  } catch (const FormatError& e) {
    error = e.what();
  }
  EXPECT_EQ(n, 4);
  EXPECT_NE(error.find("cut.pcap"), std::string::npos) << error;
  EXPECT_NE(error.find("record 4"), std::string::npos) << error;
  // Cut inside the global header / not a capture at all.
  write_bytes(t / "short.pcap", std::vector<uint8_t>(file.begin(), file.begin() + 10));
  try {
    PcapReader bad(t / "short.pcap");
    ADD_FAILURE() << "no error";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("short.pcap"), std::string::npos) << e.what();
  }
  write_bytes(t / "text.pcap", std::vector<uint8_t>(100, 'x'));
  EXPECT_THROW(PcapReader(t / "text.pcap"), FormatError);
  EXPECT_THROW(PcapReader(t / "absent.pcap"), FormatError);
  // Random corruption of the frames (not the record headers): counted, never a crash.
  auto good = read_bytes(t / "full.pcap");
  std::mt19937 fuzz(11);
  const auto recs = records_of(good);
  for (int trial = 0; trial < 200; ++trial) {
    auto b = good;
    for (int k = 0; k < 6; ++k) {
      const auto& rec = recs[fuzz() % recs.size()];
      b[rec.first + 16 + fuzz() % std::min<std::size_t>(rec.second, 60)] = static_cast<uint8_t>(fuzz());
    }
    write_bytes(t / "fuzz.pcap", b);
    PcapReader fr(t / "fuzz.pcap");
    UdpDatagram x;
    while (fr.next(x)) EXPECT_LE(x.payload.size(), 1206u + 8u);
    const auto& s = fr.stats();
    EXPECT_EQ(s.records, 5u);
    EXPECT_LE(s.datagrams + s.skipped + s.malformed, 5u + s.fragments);
  }
}

TEST(Pcap, WriterRejectsOversizedPayloads) {
  TempDir t;
  PcapWriter w(t / "x.pcap");
  UdpDatagram d;
  d.payload.resize(70000);
  EXPECT_THROW(w.write(d), std::invalid_argument);
  EXPECT_THROW(PcapWriter(t / "no" / "such" / "dir.pcap"), FormatError);
}

}  // namespace
}  // namespace cdc::io
