// pcap captures of UDP traffic (sensor packets): reading with libpcap (microsecond and nanosecond
// files; Ethernet with or without a VLAN tag, Linux cooked SLL and SLL2, raw IPv4), IPv4 fragments
// reassembled; and writing plain pcap files (nanosecond stamps, Ethernet/IPv4/UDP, fragmented past
// the MTU) by hand.
#pragma once

#include "cdc/io/error.hpp"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <tuple>
#include <vector>

namespace cdc::io {

struct UdpDatagram {
  int64_t stamp_ns = 0;             // capture time [ns since the epoch]
  uint32_t src_ip = 0, dst_ip = 0;  // IPv4, host order (127.0.0.1 = 0x7F000001)
  uint16_t src_port = 0, dst_port = 0;
  std::vector<uint8_t> payload;
  uint64_t record = 0;  // index of the capture record that completed it (0-based)
};

struct PcapStats {
  uint64_t records = 0;               // capture records read
  uint64_t datagrams = 0;             // UDP datagrams returned
  uint64_t skipped = 0;               // not IPv4/UDP (ARP, IPv6, TCP, ...)
  uint64_t snapped = 0;               // cut short by the capture's snap length (dropped)
  uint64_t malformed = 0;             // inconsistent headers (lengths, IHL) (dropped)
  uint64_t fragments = 0;             // IPv4 fragments seen
  uint64_t reassembled = 0;           // datagrams rebuilt from fragments
  uint64_t incomplete_fragments = 0;  // fragments of datagrams never completed (dropped)
};

class PcapReader {
 public:
  // Throws FormatError naming the file when it cannot be opened or is not a pcap capture, or when its
  // link type is not one listed above.
  explicit PcapReader(const std::filesystem::path& path);
  ~PcapReader();
  PcapReader(const PcapReader&) = delete;
  PcapReader& operator=(const PcapReader&) = delete;

  // The next UDP datagram; false at the end of the file. Throws FormatError naming the file and the
  // record index when the file is damaged (e.g. truncated inside a record); datagrams returned before
  // stay valid and stats() counts what was read.
  bool next(UdpDatagram& out);
  const PcapStats& stats() const { return stats_; }
  int link_type() const { return link_type_; }

 private:
  struct Fragments {
    std::map<uint32_t, std::vector<uint8_t>> pieces;  // offset -> bytes (IP payload)
    uint32_t total = 0;                               // known once the last fragment arrived
    int64_t stamp_ns = 0;
    uint64_t first_record = 0;
  };
  using FragmentKey = std::tuple<uint32_t, uint32_t, uint16_t>;  // (src, dst, id)
  bool handle_ip(std::span<const uint8_t> ip, int64_t stamp_ns, UdpDatagram& out);
  bool add_fragment(const FragmentKey& key, uint32_t offset, bool more, std::span<const uint8_t> body, int64_t stamp_ns,
                    UdpDatagram& out);
  void drop_oldest_fragments();  // the set that started earliest, to make room
  bool emit_udp(std::span<const uint8_t> udp, uint32_t src, uint32_t dst, int64_t stamp_ns, UdpDatagram& out);

  std::string path_;
  void* pcap_ = nullptr;  // pcap_t
  int link_type_ = 0;
  PcapStats stats_;
  std::map<FragmentKey, Fragments> fragments_;
};

class PcapWriter {
 public:
  // Creates (truncates) `path`; throws FormatError naming it when it cannot be written.
  explicit PcapWriter(const std::filesystem::path& path, std::size_t mtu = 1500);
  ~PcapWriter();
  PcapWriter(const PcapWriter&) = delete;
  PcapWriter& operator=(const PcapWriter&) = delete;

  // Writes one datagram as Ethernet/IPv4/UDP frames (IPv4 fragments when it exceeds the MTU). Throws
  // std::invalid_argument for a payload over 65507 bytes, FormatError on a write error.
  void write(const UdpDatagram& d);
  void close();
  uint64_t records() const { return records_; }

 private:
  void write_record(int64_t stamp_ns, const std::vector<uint8_t>& frame);

  std::string path_;
  std::FILE* file_ = nullptr;
  std::size_t mtu_;
  uint16_t next_id_ = 1;
  uint64_t records_ = 0;
};

}  // namespace cdc::io
