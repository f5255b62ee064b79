// MCAP reader written from the format specification (https://mcap.dev/spec, major version 0).
//
// The file is mapped into memory and scanned once when opened: every record is framed and checked
// against the bytes present, chunks are decompressed (and their CRC checked when the writer stored
// one), and schemas, channels and the position of every message are collected. Messages are then
// yielded in log-time order (ties in file order), decompressing a chunk again when a message of it
// is read; a few decompressed chunks are kept. The summary section is walked for framing only: the
// reader needs no index.
#include "ros2_bag.hpp"

#include "decompress.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstring>
#include <deque>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <sstream>

namespace cdc::io::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::array<uint8_t, 8> kMagic{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
constexpr uint64_t kRecordHeaderBytes = 9;  // opcode + uint64 content length
constexpr uint64_t kFooterContentBytes = 20;
constexpr uint32_t kNoChunk = std::numeric_limits<uint32_t>::max();
constexpr size_t kChunkCacheSize = 4;

enum Opcode : uint8_t {
  kHeader = 0x01,
  kFooter = 0x02,
  kSchema = 0x03,
  kChannel = 0x04,
  kMessage = 0x05,
  kChunk = 0x06,
  kDataEnd = 0x0F,
};

const char* opcode_name(uint8_t op) {
  switch (op) {
    case 0x01:
      return "Header";
    case 0x02:
      return "Footer";
    case 0x03:
      return "Schema";
    case 0x04:
      return "Channel";
    case 0x05:
      return "Message";
    case 0x06:
      return "Chunk";
    case 0x07:
      return "Message Index";
    case 0x08:
      return "Chunk Index";
    case 0x09:
      return "Attachment";
    case 0x0A:
      return "Attachment Index";
    case 0x0B:
      return "Statistics";
    case 0x0C:
      return "Metadata";
    case 0x0D:
      return "Metadata Index";
    case 0x0E:
      return "Summary Offset";
    case 0x0F:
      return "Data End";
    default:
      return "unknown";
  }
}

std::string hex(uint64_t v) {
  std::ostringstream s;
  s << "0x" << std::hex << v;
  return s.str();
}

// A read-only memory map of a whole file.
class MappedFile {
 public:
  explicit MappedFile(const fs::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) throw FormatError(path.string() + ": cannot open: " + std::strerror(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0) {
      const int err = errno;
      ::close(fd);
      throw FormatError(path.string() + ": cannot stat: " + std::strerror(err));
    }
    size_ = static_cast<size_t>(st.st_size);
    if (size_ > 0) {
      void* addr = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
      if (addr == MAP_FAILED) {
        const int err = errno;
        ::close(fd);
        throw FormatError(path.string() + ": cannot map: " + std::strerror(err));
      }
      addr_ = addr;
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (addr_ != nullptr) ::munmap(addr_, size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;

  std::span<const uint8_t> bytes() const { return {static_cast<const uint8_t*>(addr_), size_}; }

 private:
  void* addr_ = nullptr;
  size_t size_ = 0;
};

// Where a record lies, for error messages: a file offset, or an offset inside the decompressed
// records of the chunk whose record starts at chunk_offset.
struct Place {
  uint8_t opcode = 0;
  uint64_t offset = 0;
  std::optional<uint64_t> chunk_offset;
};

std::string describe_place(const Place& p) {
  std::string s = std::string("MCAP ") + opcode_name(p.opcode) + " record (opcode " + hex(p.opcode) + ")";
  if (p.chunk_offset) {
    return s + " at offset " + std::to_string(p.offset) + " of the records of the Chunk at byte " +
           std::to_string(*p.chunk_offset);
  }
  return s + " at byte " + std::to_string(p.offset);
}

// Little-endian fields of one record's content, every read checked against the content's end.
class Cursor {
 public:
  Cursor(std::span<const uint8_t> content, const std::string& name, const Place& place)
      : content_(content), name_(name), place_(place) {}

  uint8_t u8(const char* field) { return static_cast<uint8_t>(le(1, field)); }
  uint16_t u16(const char* field) { return static_cast<uint16_t>(le(2, field)); }
  uint32_t u32(const char* field) { return static_cast<uint32_t>(le(4, field)); }
  uint64_t u64(const char* field) { return le(8, field); }

  std::span<const uint8_t> take(uint64_t n, const char* field) {
    need(n, field);
    auto s = content_.subspan(pos_, static_cast<size_t>(n));
    pos_ += static_cast<size_t>(n);
    return s;
  }
  std::string str(const char* field) {
    const uint32_t n = u32(field);
    auto s = take(n, field);
    return {s.begin(), s.end()};
  }
  void skip_u32_prefixed(const char* field) { take(u32(field), field); }
  std::span<const uint8_t> rest() {
    auto s = content_.subspan(pos_);
    pos_ = content_.size();
    return s;
  }

  [[noreturn]] void fail(const std::string& what) const {
    throw FormatError(name_ + ": " + describe_place(place_) + ": " + what);
  }

 private:
  void need(uint64_t n, const char* field) const {
    if (n > content_.size() - pos_) {
      fail(std::string("field '") + field + "' needs " + std::to_string(n) + " bytes at content offset " +
           std::to_string(pos_) + ", the record has " + std::to_string(content_.size() - pos_) + " left");
    }
  }
  uint64_t le(size_t n, const char* field) {
    need(n, field);
    uint64_t v = 0;
    for (size_t i = 0; i < n; ++i) v |= uint64_t{content_[pos_ + i]} << (8 * i);
    pos_ += n;
    return v;
  }

  std::span<const uint8_t> content_;
  size_t pos_ = 0;
  const std::string& name_;
  Place place_;
};

uint64_t read_le64(const uint8_t* p) {
  uint64_t v = 0;
  for (size_t i = 0; i < 8; ++i) v |= uint64_t{p[i]} << (8 * i);
  return v;
}

enum class ChunkCompression { kNone, kZstd, kLz4 };

struct ChunkInfo {
  uint64_t record_offset = 0;  // file offset of the Chunk record
  uint64_t data_offset = 0;    // file offset of its (compressed) records field
  uint64_t data_size = 0;
  uint64_t uncompressed_size = 0;
  ChunkCompression compression = ChunkCompression::kNone;
};

struct SchemaInfo {
  std::string name, encoding;
};

struct ChannelInfo {
  uint16_t schema_id = 0;
  std::string topic, encoding;
  std::string type;  // ROS 2 spelling of the schema name; empty without schema
  bool supported = false;
  Serialization serialization = Serialization::kCdr;
  uint64_t messages = 0;
};

// Where one message's data lie: in the file (chunk == kNoChunk) or in a chunk's records.
struct Entry {
  uint64_t log_time = 0;
  uint64_t offset = 0;
  uint64_t size = 0;
  uint32_t chunk = kNoChunk;
  uint16_t channel = 0;
};

class McapBag final : public BagReader {
 public:
  McapBag(std::span<const uint8_t> file, std::string name, std::unique_ptr<MappedFile> mapped,
          std::vector<uint8_t> owned)
      : mapped_(std::move(mapped)), owned_(std::move(owned)), file_(file), name_(std::move(name)) {
    scan();
  }

  std::vector<BagTopic> topics() const override {
    std::vector<BagTopic> out;
    for (const auto& entry : channels_) {
      const auto& ch = entry.second;  // a named reference: clang 14 cannot capture a structured binding
      auto it = std::find_if(out.begin(), out.end(), [&](const BagTopic& t) {
        return t.name == ch.topic && t.type == ch.type && t.encoding == ch.encoding;
      });
      if (it == out.end()) {
        out.push_back(BagTopic{ch.topic, ch.type, ch.messages, ch.encoding});
      } else {
        it->messages += ch.messages;
      }
    }
    return out;
  }

  bool next(BagMessage& out) override {
    if (next_ >= entries_.size()) return false;
    const Entry& e = entries_[next_++];
    const ChannelInfo& ch = channels_.at(e.channel);
    std::span<const uint8_t> source = e.chunk == kNoChunk ? file_ : chunk_records(e.chunk);
    auto data = source.subspan(static_cast<size_t>(e.offset), static_cast<size_t>(e.size));
    out.topic = ch.topic;
    out.type = ch.type;
    out.log_time_ns = static_cast<int64_t>(e.log_time);
    out.serialization = ch.serialization;
    out.data.assign(data.begin(), data.end());
    return true;
  }

  std::string describe() const override { return "MCAP file " + name_; }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw FormatError(name_ + ": " + what); }

  // The record framed at pos of `bytes` ([pos, limit) available): opcode and content.
  struct Framed {
    uint8_t opcode;
    std::span<const uint8_t> content;
    uint64_t end;
  };
  Framed frame(std::span<const uint8_t> bytes, uint64_t pos, uint64_t limit,
               std::optional<uint64_t> chunk_offset) const {
    auto where = [&] {
      return chunk_offset ? "offset " + std::to_string(pos) + " of the records of the Chunk at byte " +
                                std::to_string(*chunk_offset)
                          : "byte " + std::to_string(pos);
    };
    if (limit - pos < kRecordHeaderBytes) {
      fail("MCAP record header at " + where() + " needs 9 bytes, only " + std::to_string(limit - pos) +
           " remain (truncated)");
    }
    const uint8_t op = bytes[static_cast<size_t>(pos)];
    const uint64_t len = read_le64(bytes.data() + pos + 1);
    if (len > limit - pos - kRecordHeaderBytes) {
      fail(std::string("MCAP ") + opcode_name(op) + " record (opcode " + hex(op) + ") at " + where() + " claims " +
           std::to_string(len) + " content bytes, only " + std::to_string(limit - pos - kRecordHeaderBytes) +
           " remain (truncated or damaged)");
    }
    const uint64_t start = pos + kRecordHeaderBytes;
    return {op, bytes.subspan(static_cast<size_t>(start), static_cast<size_t>(len)), start + len};
  }

  void scan() {
    if (file_.size() < kMagic.size() || !std::equal(kMagic.begin(), kMagic.end(), file_.begin())) {
      fail("does not start with the MCAP magic (byte 0)");
    }
    const uint64_t min_size = 2 * kMagic.size() + 2 * kRecordHeaderBytes + kFooterContentBytes;
    if (file_.size() < min_size) {
      fail("truncated: " + std::to_string(file_.size()) + " bytes, an MCAP file has at least " +
           std::to_string(min_size));
    }
    const uint64_t end = file_.size() - kMagic.size();
    if (!std::equal(kMagic.begin(), kMagic.end(), file_.begin() + static_cast<std::ptrdiff_t>(end))) {
      fail("truncated or damaged: no MCAP magic at the end (byte " + std::to_string(end) + " of " +
           std::to_string(file_.size()) + ")");
    }
    uint64_t pos = kMagic.size();
    bool first = true, footer = false;
    while (pos < end) {
      const Framed r = frame(file_, pos, end, std::nullopt);
      const Place place{r.opcode, pos, std::nullopt};
      if (first && r.opcode != kHeader) {
        fail(std::string("the first record (byte ") + std::to_string(pos) + ") is " + opcode_name(r.opcode) +
             ", not Header");
      }
      first = false;
      switch (r.opcode) {
        case kHeader: {
          Cursor c(r.content, name_, place);
          c.str("profile");
          c.str("library");
          break;
        }
        case kFooter:
          if (r.end != end) {
            fail("MCAP Footer record at byte " + std::to_string(pos) + " is not the last record (it ends at byte " +
                 std::to_string(r.end) + ", the closing magic is at byte " + std::to_string(end) + ")");
          }
          if (r.content.size() < kFooterContentBytes) {
            Cursor(r.content, name_, place)
                .fail("Footer content has " + std::to_string(r.content.size()) + " bytes, 20 expected");
          }
          footer = true;
          break;
        case kChunk:
          on_chunk(r.content, place, pos);
          break;
        default:
          // Schema, Channel, Message; indexes, attachments, metadata, statistics, summary offsets and
          // data end are skipped.
          on_data_record(r, place, kNoChunk, pos);
          break;
      }
      pos = r.end;
    }
    if (!footer) fail("no Footer record before the closing magic at byte " + std::to_string(end));
    std::stable_sort(entries_.begin(), entries_.end(),
                     [](const Entry& a, const Entry& b) { return a.log_time < b.log_time; });
  }

  // A Schema, Channel or Message record, at the top level (kNoChunk) or in a chunk, `pos` the byte
  // where its header starts; other records are skipped.
  void on_data_record(const Framed& r, const Place& place, uint32_t chunk, uint64_t pos) {
    switch (r.opcode) {
      case kSchema:
        on_schema(r.content, place);
        break;
      case kChannel:
        on_channel(r.content, place);
        break;
      case kMessage:
        on_message(r.content, place, chunk, pos + kRecordHeaderBytes);
        break;
      default:
        break;
    }
  }

  void on_schema(std::span<const uint8_t> content, const Place& place) {
    Cursor c(content, name_, place);
    const uint16_t id = c.u16("id");
    SchemaInfo s{c.str("name"), c.str("encoding")};
    c.skip_u32_prefixed("data");
    if (id == 0) return;  // invalid id, ignored as the specification says
    auto [it, inserted] = schemas_.emplace(id, s);
    if (!inserted && (it->second.name != s.name || it->second.encoding != s.encoding)) {
      c.fail("schema " + std::to_string(id) + " redefined as '" + s.name + "' (was '" + it->second.name + "')");
    }
  }

  void on_channel(std::span<const uint8_t> content, const Place& place) {
    Cursor c(content, name_, place);
    const uint16_t id = c.u16("id");
    ChannelInfo ch;
    ch.schema_id = c.u16("schema_id");
    ch.topic = c.str("topic");
    ch.encoding = c.str("message_encoding");
    c.skip_u32_prefixed("metadata");
    if (ch.schema_id != 0) {
      auto s = schemas_.find(ch.schema_id);
      if (s == schemas_.end()) {
        c.fail("channel " + std::to_string(id) + " (" + ch.topic + ") refers to schema " +
               std::to_string(ch.schema_id) + ", which no earlier Schema record defines");
      }
      ch.type = ros2_type_name(s->second.name);
    }
    ch.supported = ch.encoding == "cdr" || ch.encoding == "ros1";
    ch.serialization = ch.encoding == "ros1" ? Serialization::kRos1 : Serialization::kCdr;
    auto [it, inserted] = channels_.emplace(id, ch);
    if (!inserted &&
        (it->second.topic != ch.topic || it->second.schema_id != ch.schema_id || it->second.encoding != ch.encoding)) {
      c.fail("channel " + std::to_string(id) + " redefined as " + ch.topic + " (was " + it->second.topic + ")");
    }
  }

  // data_base: where the record's content starts in its buffer (file, or chunk records).
  void on_message(std::span<const uint8_t> content, const Place& place, uint32_t chunk, uint64_t data_base) {
    Cursor c(content, name_, place);
    const uint16_t channel = c.u16("channel_id");
    c.u32("sequence");
    const uint64_t log_time = c.u64("log_time");
    c.u64("publish_time");
    const uint64_t header_bytes = 2 + 4 + 8 + 8;
    auto it = channels_.find(channel);
    if (it == channels_.end()) {
      c.fail("message on channel " + std::to_string(channel) + ", which no earlier Channel record defines");
    }
    if (log_time > static_cast<uint64_t>(std::numeric_limits<int64_t>::max())) {
      c.fail("log_time " + std::to_string(log_time) + " does not fit a signed 64-bit nanosecond count");
    }
    ++it->second.messages;
    if (!it->second.supported) return;
    entries_.push_back(Entry{log_time, data_base + header_bytes, content.size() - header_bytes, chunk, channel});
  }

  void on_chunk(std::span<const uint8_t> content, const Place& place, uint64_t record_offset) {
    Cursor c(content, name_, place);
    c.u64("message_start_time");
    c.u64("message_end_time");
    ChunkInfo info;
    info.record_offset = record_offset;
    info.uncompressed_size = c.u64("uncompressed_size");
    const uint32_t crc = c.u32("uncompressed_crc");
    const std::string compression = c.str("compression");
    const uint64_t records_size = c.u64("records length");
    auto records = c.take(records_size, "records");
    info.data_offset = static_cast<uint64_t>(records.data() - file_.data());
    info.data_size = records.size();
    const std::string where = name_ + ": " + describe_place(place);
    std::vector<uint8_t> decompressed;
    std::span<const uint8_t> plain;
    if (compression.empty()) {
      info.compression = ChunkCompression::kNone;
      if (info.uncompressed_size != records.size()) {
        c.fail("uncompressed chunk holds " + std::to_string(records.size()) + " bytes of records, its header says " +
               std::to_string(info.uncompressed_size));
      }
      plain = records;
    } else if (compression == "zstd") {
      info.compression = ChunkCompression::kZstd;
      decompressed = zstd_decompress(records, info.uncompressed_size, where);
      plain = decompressed;
    } else if (compression == "lz4") {
      info.compression = ChunkCompression::kLz4;
      decompressed = lz4_decompress(records, info.uncompressed_size, where);
      plain = decompressed;
    } else {
      c.fail("unsupported chunk compression '" + compression + "' (supported: none, zstd, lz4)");
    }
    if (crc != 0) {
      const uint32_t actual = crc32(plain);
      if (actual != crc) {
        c.fail("CRC mismatch of the uncompressed records: stored " + hex(crc) + ", computed " + hex(actual));
      }
    }
    if (chunks_.size() >= kNoChunk) c.fail("too many chunks");
    const auto chunk_index = static_cast<uint32_t>(chunks_.size());
    chunks_.push_back(info);
    uint64_t pos = 0;
    while (pos < plain.size()) {
      const Framed r = frame(plain, pos, plain.size(), record_offset);
      const Place inner{r.opcode, pos, record_offset};
      on_data_record(r, inner, chunk_index, pos);  // the specification allows no other records in a chunk
      pos = r.end;
    }
  }

  // The uncompressed records of chunk i, from the cache or decoded again.
  std::span<const uint8_t> chunk_records(uint32_t i) {
    const ChunkInfo& info = chunks_[i];
    auto stored = file_.subspan(static_cast<size_t>(info.data_offset), static_cast<size_t>(info.data_size));
    if (info.compression == ChunkCompression::kNone) return stored;
    for (const auto& [index, bytes] : cache_) {
      if (index == i) return bytes;
    }
    const std::string where = name_ + ": MCAP Chunk record at byte " + std::to_string(info.record_offset);
    std::vector<uint8_t> plain = info.compression == ChunkCompression::kZstd
                                     ? zstd_decompress(stored, info.uncompressed_size, where)
                                     : lz4_decompress(stored, info.uncompressed_size, where);
    if (cache_.size() >= kChunkCacheSize) cache_.pop_front();
    cache_.emplace_back(i, std::move(plain));
    return cache_.back().second;
  }

  std::unique_ptr<MappedFile> mapped_;
  std::vector<uint8_t> owned_;
  std::span<const uint8_t> file_;
  std::string name_;
  std::map<uint16_t, SchemaInfo> schemas_;
  std::map<uint16_t, ChannelInfo> channels_;
  std::vector<ChunkInfo> chunks_;
  std::vector<Entry> entries_;
  size_t next_ = 0;
  std::deque<std::pair<uint32_t, std::vector<uint8_t>>> cache_;
};

}  // namespace

std::unique_ptr<BagReader> open_mcap_bag(const fs::path& path) {
  auto mapped = std::make_unique<MappedFile>(path);
  const auto bytes = mapped->bytes();
  return std::make_unique<McapBag>(bytes, path.string(), std::move(mapped), std::vector<uint8_t>{});
}

std::unique_ptr<BagReader> open_mcap_bag_bytes(std::vector<uint8_t> bytes, const std::string& name) {
  const std::span<const uint8_t> view(bytes.data(), bytes.size());  // stays valid when the vector moves
  return std::make_unique<McapBag>(view, name, nullptr, std::move(bytes));
}

}  // namespace cdc::io::detail
