#include "cdc/io/pcap.hpp"

#include "cdc/io/error.hpp"

#include <pcap/pcap.h>

#include <algorithm>
#include <stdexcept>

namespace cdc::io {
namespace {

constexpr int kLinkEthernet = 1;  // DLT_EN10MB
constexpr int kLinkRaw = 101;     // LINKTYPE_RAW (libpcap reports DLT_RAW = 12 or 14 on some systems)
constexpr int kLinkSll = 113;     // DLT_LINUX_SLL
constexpr int kLinkSll2 = 276;    // DLT_LINUX_SLL2
constexpr uint16_t kEtherIpv4 = 0x0800, kEtherVlan = 0x8100, kEtherQinq = 0x88A8;
constexpr std::size_t kMaxPendingDatagrams = 256;  // fragment sets kept before the oldest is dropped

uint16_t be16(std::span<const uint8_t> b, std::size_t at) { return static_cast<uint16_t>((b[at] << 8) | b[at + 1]); }
uint32_t be32(std::span<const uint8_t> b, std::size_t at) {
  return (static_cast<uint32_t>(b[at]) << 24) | (static_cast<uint32_t>(b[at + 1]) << 16) |
         (static_cast<uint32_t>(b[at + 2]) << 8) | b[at + 3];
}
void put16(std::vector<uint8_t>& v, uint16_t x) {
  v.push_back(static_cast<uint8_t>(x >> 8));
  v.push_back(static_cast<uint8_t>(x & 0xFF));
}
void put32(std::vector<uint8_t>& v, uint32_t x) {
  put16(v, static_cast<uint16_t>(x >> 16));
  put16(v, static_cast<uint16_t>(x & 0xFFFF));
}

}  // namespace

// ---------------------------------------------------------------------------------------------

PcapReader::PcapReader(const std::filesystem::path& path) : path_(path.string()) {
  char err[PCAP_ERRBUF_SIZE] = {0};
  pcap_t* p = pcap_open_offline_with_tstamp_precision(path_.c_str(), PCAP_TSTAMP_PRECISION_NANO, err);
  if (p == nullptr) throw FormatError(path_ + ": not a readable pcap capture: " + err);
  pcap_ = p;
  link_type_ = pcap_datalink(p);
  if (link_type_ == 12 || link_type_ == 14) link_type_ = kLinkRaw;  // DLT_RAW on BSD / OpenBSD
  if (link_type_ != kLinkEthernet && link_type_ != kLinkRaw && link_type_ != kLinkSll && link_type_ != kLinkSll2) {
    const int lt = link_type_;
    pcap_close(p);
    pcap_ = nullptr;
    throw FormatError(path_ + ": link type " + std::to_string(lt) +
                      " is not Ethernet, Linux cooked (SLL, SLL2) or raw IP");
  }
}

PcapReader::~PcapReader() {
  if (pcap_ != nullptr) pcap_close(static_cast<pcap_t*>(pcap_));
}

bool PcapReader::next(UdpDatagram& out) {
  auto* p = static_cast<pcap_t*>(pcap_);
  for (;;) {
    pcap_pkthdr* h = nullptr;
    const u_char* data = nullptr;
    const int rc = pcap_next_ex(p, &h, &data);
    if (rc == PCAP_ERROR_BREAK) {  // end of file
      for (const auto& [key, f] : fragments_) stats_.incomplete_fragments += f.pieces.size();
      fragments_.clear();
      return false;
    }
    if (rc != 1) {
      throw FormatError(path_ + ": record " + std::to_string(stats_.records) + ": " + pcap_geterr(p));
    }
    const uint64_t record = stats_.records++;
    const int64_t stamp_ns = static_cast<int64_t>(h->ts.tv_sec) * 1000000000 + static_cast<int64_t>(h->ts.tv_usec);
    if (h->caplen < h->len) {
      ++stats_.snapped;
      continue;
    }
    const std::span<const uint8_t> frame(data, h->caplen);
    std::size_t at = 0;
    uint16_t proto = 0;
    switch (link_type_) {
      case kLinkEthernet:
        if (frame.size() < 14) break;
        proto = be16(frame, 12);
        at = 14;
        while ((proto == kEtherVlan || proto == kEtherQinq) && frame.size() >= at + 4) {
          proto = be16(frame, at + 2);
          at += 4;
        }
        break;
      case kLinkSll:
        if (frame.size() < 16) break;
        proto = be16(frame, 14);
        at = 16;
        break;
      case kLinkSll2:
        if (frame.size() < 20) break;
        proto = be16(frame, 0);
        at = 20;
        break;
      default:  // raw IP
        proto = frame.empty() || (frame[0] >> 4) != 4 ? 0 : kEtherIpv4;
        at = 0;
        break;
    }
    if (proto != kEtherIpv4 || at > frame.size()) {
      ++stats_.skipped;
      continue;
    }
    out.record = record;
    if (handle_ip(frame.subspan(at), stamp_ns, out)) return true;
  }
}

bool PcapReader::handle_ip(std::span<const uint8_t> ip, int64_t stamp_ns, UdpDatagram& out) {
  if (ip.size() < 20 || (ip[0] >> 4) != 4) {
    ++stats_.malformed;
    return false;
  }
  const std::size_t ihl = static_cast<std::size_t>(ip[0] & 0x0F) * 4;
  const std::size_t total = be16(ip, 2);
  if (ihl < 20 || total < ihl || total > ip.size()) {
    ++stats_.malformed;
    return false;
  }
  if (ip[9] != 17) {  // not UDP
    ++stats_.skipped;
    return false;
  }
  const uint32_t src = be32(ip, 12), dst = be32(ip, 16);
  const uint16_t flags_offset = be16(ip, 6);
  const bool more = (flags_offset & 0x2000) != 0;
  const uint32_t offset = static_cast<uint32_t>(flags_offset & 0x1FFF) * 8;
  const std::span<const uint8_t> body = ip.subspan(ihl, total - ihl);
  if (!more && offset == 0) return emit_udp(body, src, dst, stamp_ns, out);
  return add_fragment({src, dst, be16(ip, 4)}, offset, more, body, stamp_ns, out);
}

// Keeps a fragment until every byte of its datagram has arrived, then emits the datagram whole.
bool PcapReader::add_fragment(const FragmentKey& key, uint32_t offset, bool more, std::span<const uint8_t> body,
                              int64_t stamp_ns, UdpDatagram& out) {
  ++stats_.fragments;
  auto it = fragments_.find(key);
  if (it == fragments_.end()) {
    if (fragments_.size() >= kMaxPendingDatagrams) drop_oldest_fragments();
    it = fragments_.emplace(key, Fragments{}).first;
    it->second.first_record = out.record;
  }
  Fragments& f = it->second;
  if (offset + body.size() > 65535 || (more && body.size() % 8 != 0)) {
    stats_.incomplete_fragments += f.pieces.size() + 1;
    ++stats_.malformed;
    fragments_.erase(it);
    return false;
  }
  f.pieces[offset] = std::vector<uint8_t>(body.begin(), body.end());
  f.stamp_ns = stamp_ns;
  if (!more) f.total = offset + static_cast<uint32_t>(body.size());
  if (f.total == 0) return false;
  // Complete when the pieces cover [0, total) without a hole.
  uint32_t covered = 0;
  for (const auto& [o, bytes] : f.pieces) {
    if (o > covered) return false;
    covered = std::max(covered, o + static_cast<uint32_t>(bytes.size()));
  }
  if (covered < f.total) return false;
  std::vector<uint8_t> whole(f.total);
  for (const auto& [o, bytes] : f.pieces) {
    const std::size_t n = std::min<std::size_t>(bytes.size(), f.total - o);
    std::copy_n(bytes.begin(), n, whole.begin() + o);
  }
  fragments_.erase(it);
  ++stats_.reassembled;
  return emit_udp(whole, std::get<0>(key), std::get<1>(key), stamp_ns, out);
}

void PcapReader::drop_oldest_fragments() {
  auto oldest = fragments_.begin();
  for (auto f = fragments_.begin(); f != fragments_.end(); ++f) {
    if (f->second.first_record < oldest->second.first_record) oldest = f;
  }
  stats_.incomplete_fragments += oldest->second.pieces.size();
  fragments_.erase(oldest);
}

bool PcapReader::emit_udp(std::span<const uint8_t> udp, uint32_t src, uint32_t dst, int64_t stamp_ns,
                          UdpDatagram& out) {
  if (udp.size() < 8) {
    ++stats_.malformed;
    return false;
  }
  const std::size_t length = be16(udp, 4);
  if (length < 8 || length > udp.size()) {
    ++stats_.malformed;
    return false;
  }
  out.stamp_ns = stamp_ns;
  out.src_ip = src;
  out.dst_ip = dst;
  out.src_port = be16(udp, 0);
  out.dst_port = be16(udp, 2);
  out.payload.assign(udp.begin() + 8, udp.begin() + static_cast<std::ptrdiff_t>(length));
  ++stats_.datagrams;
  return true;
}

// ---------------------------------------------------------------------------------------------

PcapWriter::PcapWriter(const std::filesystem::path& path, std::size_t mtu) : path_(path.string()), mtu_(mtu) {
  if (mtu_ < 68 || mtu_ > 65535) throw std::invalid_argument("pcap writer: MTU must lie in 68..65535");
  file_ = std::fopen(path_.c_str(), "wb");
  if (file_ == nullptr) throw FormatError(path_ + ": cannot be created");
  // Global header, little-endian: nanosecond magic, version 2.4, zone 0, sigfigs 0, snaplen, Ethernet.
  const uint32_t header[6] = {0xA1B23C4D, 0x00040002, 0, 0, 262144, kLinkEthernet};
  std::vector<uint8_t> bytes;
  for (const uint32_t w : header) {
    for (int i = 0; i < 4; ++i) bytes.push_back(static_cast<uint8_t>(w >> (8 * i)));
  }
  if (std::fwrite(bytes.data(), 1, bytes.size(), file_) != bytes.size()) throw FormatError(path_ + ": write error");
}

PcapWriter::~PcapWriter() {
  if (file_ != nullptr) std::fclose(file_);
}

void PcapWriter::close() {
  if (file_ != nullptr && std::fclose(file_) != 0) {
    file_ = nullptr;
    throw FormatError(path_ + ": write error on close");
  }
  file_ = nullptr;
}

void PcapWriter::write_record(int64_t stamp_ns, const std::vector<uint8_t>& frame) {
  if (file_ == nullptr) throw FormatError(path_ + ": written after close");
  const auto sec = static_cast<uint32_t>(stamp_ns / 1000000000);
  const auto nsec = static_cast<uint32_t>(stamp_ns % 1000000000);
  const auto len = static_cast<uint32_t>(frame.size());
  const uint32_t header[4] = {sec, nsec, len, len};
  uint8_t bytes[16];
  for (int w = 0; w < 4; ++w) {
    for (int i = 0; i < 4; ++i) bytes[4 * w + i] = static_cast<uint8_t>(header[w] >> (8 * i));
  }
  if (std::fwrite(bytes, 1, 16, file_) != 16 || std::fwrite(frame.data(), 1, frame.size(), file_) != frame.size()) {
    throw FormatError(path_ + ": write error at record " + std::to_string(records_));
  }
  ++records_;
}

void PcapWriter::write(const UdpDatagram& d) {
  if (d.payload.size() > 65507) throw std::invalid_argument("pcap writer: UDP payload over 65507 bytes");
  if (d.stamp_ns < 0) throw std::invalid_argument("pcap writer: negative stamp");
  // The UDP datagram (checksum 0: none, as IPv4 allows).
  std::vector<uint8_t> udp;
  put16(udp, d.src_port);
  put16(udp, d.dst_port);
  put16(udp, static_cast<uint16_t>(8 + d.payload.size()));
  put16(udp, 0);
  udp.insert(udp.end(), d.payload.begin(), d.payload.end());
  const std::size_t max_body = (mtu_ - 20) / 8 * 8;
  const uint16_t id = next_id_++;
  for (std::size_t offset = 0; offset < udp.size(); offset += max_body) {
    const std::size_t n = std::min(max_body, udp.size() - offset);
    const bool more = offset + n < udp.size();
    std::vector<uint8_t> frame = {0x00, 0x00, 0x00, 0x00, 0x00, 0x00,   // destination MAC
                                  0x02, 0x00, 0x00, 0x00, 0x00, 0x01};  // source MAC (locally administered)
    put16(frame, kEtherIpv4);
    const std::size_t ip_at = frame.size();
    frame.push_back(0x45);  // IPv4, 20-byte header
    frame.push_back(0);
    put16(frame, static_cast<uint16_t>(20 + n));
    put16(frame, id);
    put16(frame, static_cast<uint16_t>((more ? 0x2000 : 0) | (offset / 8)));
    frame.push_back(64);  // TTL
    frame.push_back(17);  // UDP
    put16(frame, 0);      // checksum, below
    put32(frame, d.src_ip);
    put32(frame, d.dst_ip);
    uint32_t sum = 0;
    for (std::size_t i = 0; i < 20; i += 2)
      sum += static_cast<uint32_t>((frame[ip_at + i] << 8) | frame[ip_at + i + 1]);
    while ((sum >> 16) != 0) sum = (sum & 0xFFFF) + (sum >> 16);
    const auto checksum = static_cast<uint16_t>(~sum & 0xFFFF);
    frame[ip_at + 10] = static_cast<uint8_t>(checksum >> 8);
    frame[ip_at + 11] = static_cast<uint8_t>(checksum & 0xFF);
    frame.insert(frame.end(), udp.begin() + static_cast<std::ptrdiff_t>(offset),
                 udp.begin() + static_cast<std::ptrdiff_t>(offset + n));
    write_record(d.stamp_ns, frame);
  }
}

}  // namespace cdc::io
