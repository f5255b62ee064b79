// ROS 1 bag format 2.0 (http://wiki.ros.org/Bags/Format/2.0). A bag is the version line
// "#ROSBAG V2.0\n" followed by records; a record is
//   uint32 header_len, header (fields: uint32 len, "name=value"), uint32 data_len, data.
// The header's 'op' field says what the record is: the bag header (padded to 4096 bytes, with the
// position of the index section), chunks (compressed groups of connection and message data
// records), the index data records after each chunk (time and offset of each message in the chunk,
// per connection) and, at the end, the index section (connection records and chunk info records).
//
// Opening scans the top-level records (headers only; chunk data is skipped). A chunk whose index
// data records are present and refer to known connections is indexed without decompression; any
// other chunk (bag not closed cleanly, index cut off) is decompressed once to list its messages.
// next() walks the messages sorted by log time across all chunks, decompressing each chunk when its
// first message is due and releasing it after its last, so memory holds only chunks that overlap
// in time. Damage found while scanning is reported by next() after the messages of the intact
// chunks before it.

#include "ros1_bag.hpp"

#include "decompress.hpp"
#include "ros2_bag.hpp"

#include <bzlib.h>

#include <algorithm>
#include <cstdint>
#include <fstream>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

namespace cdc::io {
namespace {

constexpr std::string_view kVersionLine = "#ROSBAG V2.0\n";
constexpr uint8_t kOpMessageData = 0x02;
constexpr uint8_t kOpBagHeader = 0x03;
constexpr uint8_t kOpIndexData = 0x04;
constexpr uint8_t kOpChunk = 0x05;
constexpr uint8_t kOpChunkInfo = 0x06;
constexpr uint8_t kOpConnection = 0x07;
constexpr uint32_t kIndexDataVersion = 1;
constexpr uint32_t kChunkInfoVersion = 1;
constexpr uint64_t kIndexEntryBytes = 12;        // time (uint32 sec, uint32 nsec) + uint32 offset
constexpr uint64_t kChunkInfoEntryBytes = 8;     // uint32 conn + uint32 count
constexpr uint32_t kMaxHeaderBytes = 16u << 20;  // record headers hold a few short fields
constexpr uint32_t kLooseMessage = UINT32_MAX;   // Entry::chunk of a message outside any chunk

uint32_t load_u32(const uint8_t* p) {
  return static_cast<uint32_t>(p[0]) | (static_cast<uint32_t>(p[1]) << 8u) | (static_cast<uint32_t>(p[2]) << 16u) |
         (static_cast<uint32_t>(p[3]) << 24u);
}

uint64_t load_u64(const uint8_t* p) {
  return static_cast<uint64_t>(load_u32(p)) | (static_cast<uint64_t>(load_u32(p + 4)) << 32u);
}

// ROS 1 time: uint32 sec, uint32 nsec.
int64_t load_time_ns(const uint8_t* p) {
  return static_cast<int64_t>(load_u32(p)) * 1'000'000'000 + static_cast<int64_t>(load_u32(p + 4));
}

// Names a place in the bag for error messages: a file offset, or an offset in the uncompressed
// data of the chunk record at chunk_pos.
struct Locator {
  std::string path;
  std::optional<uint64_t> chunk_pos;

  [[noreturn]] void fail(uint64_t offset, const std::string& what) const {
    std::string where = path + ": ";
    if (chunk_pos) {
      where += "chunk at byte " + std::to_string(*chunk_pos) + ", uncompressed byte ";
    } else {
      where += "byte ";
    }
    throw FormatError(where + std::to_string(offset) + ": " + what);
  }
};

// The name=value fields of a record header (or of a connection record's data).
class Fields {
 public:
  // bytes start at offset pos; record_pos is where the record starts (named in errors).
  Fields(std::span<const uint8_t> bytes, uint64_t pos, uint64_t record_pos, const Locator& loc)
      : record_pos_(record_pos), loc_(&loc) {
    size_t i = 0;
    while (i < bytes.size()) {
      if (bytes.size() - i < 4) {
        loc.fail(pos + i,
                 "header field length needs 4 bytes, " + std::to_string(bytes.size() - i) + " remain in the header");
      }
      const uint32_t len = load_u32(bytes.data() + i);
      i += 4;
      if (len > bytes.size() - i) {
        loc.fail(pos + i - 4, "header field of " + std::to_string(len) + " bytes runs past the end of " +
                                  "its header (" + std::to_string(bytes.size() - i) + " bytes remain)");
      }
      const std::string_view field(reinterpret_cast<const char*>(bytes.data() + i), len);
      const size_t eq = field.find('=');
      if (eq == std::string_view::npos) loc.fail(pos + i, "header field without '='");
      values_.insert_or_assign(std::string(field.substr(0, eq)), std::string(field.substr(eq + 1)));
      i += len;
    }
  }

  bool has(std::string_view name) const { return values_.find(name) != values_.end(); }

  const std::string& str(std::string_view name) const {
    const auto it = values_.find(name);
    if (it == values_.end()) {
      loc_->fail(record_pos_, "record header has no '" + std::string(name) + "' field");
    }
    return it->second;
  }
  uint8_t u8(std::string_view name) const { return *sized(name, 1); }
  uint32_t u32(std::string_view name) const { return load_u32(sized(name, 4)); }
  uint64_t u64(std::string_view name) const { return load_u64(sized(name, 8)); }
  int64_t time_ns(std::string_view name) const { return load_time_ns(sized(name, 8)); }

 private:
  const uint8_t* sized(std::string_view name, size_t size) const {
    const std::string& v = str(name);
    if (v.size() != size) {
      loc_->fail(record_pos_, "header field '" + std::string(name) + "' has " + std::to_string(v.size()) +
                                  " bytes, expected " + std::to_string(size));
    }
    return reinterpret_cast<const uint8_t*>(v.data());
  }

  std::map<std::string, std::string, std::less<>> values_;
  uint64_t record_pos_;
  const Locator* loc_;
};

// Random access to the bag file; every read is checked against the file size by the caller.
class BagFile {
 public:
  explicit BagFile(const std::filesystem::path& path) : in_(path, std::ios::binary) {
    std::error_code ec;
    size_ = std::filesystem::file_size(path, ec);
    if (!in_ || ec) throw FormatError(path.string() + ": cannot open the file");
  }
  uint64_t size() const { return size_; }
  void read(uint64_t pos, uint8_t* dst, uint64_t n, const Locator& loc) {
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(pos));
    in_.read(reinterpret_cast<char*>(dst), static_cast<std::streamsize>(n));
    if (!in_ || static_cast<uint64_t>(in_.gcount()) != n) {
      loc.fail(pos, "cannot read " + std::to_string(n) + " bytes");
    }
  }
  std::vector<uint8_t> read(uint64_t pos, uint64_t n, const Locator& loc) {
    std::vector<uint8_t> out(n);
    read(pos, out.data(), n, loc);
    return out;
  }

 private:
  std::ifstream in_;
  uint64_t size_ = 0;
};

// A record: its header is read, its data only located.
struct Record {
  uint64_t pos = 0;
  std::optional<Fields> header;
  uint64_t data_pos = 0;
  uint32_t data_len = 0;
  uint64_t end = 0;
  uint8_t op = 0;
};

// Records in the file, read on demand; a record header may not exceed kMaxHeaderBytes.
struct FileBytes {
  static constexpr const char* kName = "file";
  static constexpr uint64_t kMaxHeader = kMaxHeaderBytes;
  BagFile& file;

  uint64_t size() const { return file.size(); }
  uint32_t u32(uint64_t pos, const Locator& loc) const {
    uint8_t bytes[4];
    file.read(pos, bytes, 4, loc);
    return load_u32(bytes);
  }
  std::vector<uint8_t> bytes(uint64_t pos, uint64_t n, const Locator& loc) const { return file.read(pos, n, loc); }
};

// Records in a chunk's uncompressed data, in memory; the chunk bounds a record header.
struct ChunkBytes {
  static constexpr const char* kName = "chunk";
  static constexpr uint64_t kMaxHeader = 0;  // none
  std::span<const uint8_t> buf;

  uint64_t size() const { return buf.size(); }
  uint32_t u32(uint64_t pos, const Locator&) const { return load_u32(buf.data() + pos); }
  std::span<const uint8_t> bytes(uint64_t pos, uint64_t n, const Locator&) const { return buf.subspan(pos, n); }
};

// The record at pos: uint32 header length, header, uint32 data length, data; every length checked
// against the bytes of the source.
template <class Source>
Record read_record(const Source& src, uint64_t pos, const Locator& loc) {
  const uint64_t size = src.size();
  const std::string end_of = std::string(" the ") + Source::kName;
  Record r;
  r.pos = pos;
  if (size - pos < 4) {
    loc.fail(pos, "record header length needs 4 bytes," + end_of + " ends at byte " + std::to_string(size));
  }
  const uint32_t header_len = src.u32(pos, loc);
  if (header_len > size - pos - 4) {
    loc.fail(pos, "record header of " + std::to_string(header_len) + " bytes runs past the end of" + end_of + " (" +
                      std::to_string(size) + " bytes)");
  }
  if constexpr (Source::kMaxHeader != 0) {
    if (header_len > Source::kMaxHeader) {
      loc.fail(pos, "record header of " + std::to_string(header_len) + " bytes exceeds the " +
                        std::to_string(Source::kMaxHeader) + " bytes this reader accepts");
    }
  }
  r.header.emplace(src.bytes(pos + 4, header_len, loc), pos + 4, pos, loc);
  r.op = r.header->u8("op");
  r.data_pos = pos + 4 + header_len;
  if (size - r.data_pos < 4) {
    loc.fail(r.data_pos, "record data length needs 4 bytes," + end_of + " ends at byte " + std::to_string(size));
  }
  r.data_len = src.u32(r.data_pos, loc);
  r.data_pos += 4;
  if (r.data_len > size - r.data_pos) {
    loc.fail(r.data_pos - 4, "record data of " + std::to_string(r.data_len) + " bytes runs past the end of" + end_of +
                                 " (" + std::to_string(size) + " bytes)");
  }
  r.end = r.data_pos + r.data_len;
  return r;
}

// Output buffer for a decompressor: grows as data arrives, up to one byte more than the declared
// size (so that too much data is noticed), so a corrupt size field costs no large allocation.
class Inflated {
 public:
  Inflated(uint32_t declared, uint64_t compressed_bytes) : limit_(uint64_t{declared} + 1) {
    buf_.resize(std::min<uint64_t>(limit_, 4 * compressed_bytes + 65536));
  }
  // Free space at the end, growing the buffer if it is full; empty when the limit is reached.
  std::span<uint8_t> space() {
    if (used_ == buf_.size() && buf_.size() < limit_) {
      buf_.resize(std::min<uint64_t>(limit_, 2 * buf_.size()));
    }
    return std::span<uint8_t>(buf_).subspan(used_);
  }
  void produced(uint64_t n) { used_ += n; }
  uint64_t used() const { return used_; }
  std::vector<uint8_t> take() {
    buf_.resize(used_);
    return std::move(buf_);
  }

 private:
  uint64_t limit_;
  std::vector<uint8_t> buf_;
  uint64_t used_ = 0;
};

std::string bz2_error_name(int rc) {
  switch (rc) {
    case BZ_DATA_ERROR:
      return "data integrity error (BZ_DATA_ERROR)";
    case BZ_DATA_ERROR_MAGIC:
      return "no bz2 stream magic (BZ_DATA_ERROR_MAGIC)";
    case BZ_MEM_ERROR:
      return "out of memory (BZ_MEM_ERROR)";
    case BZ_PARAM_ERROR:
      return "parameter error (BZ_PARAM_ERROR)";
    default:
      return "error code " + std::to_string(rc);
  }
}

// data: the chunk's compressed bytes, which start at file offset data_pos.
std::vector<uint8_t> inflate_bz2(std::span<const uint8_t> data, uint32_t declared, uint64_t data_pos,
                                 const Locator& loc) {
  bz_stream s{};
  if (const int rc = BZ2_bzDecompressInit(&s, 0, 0); rc != BZ_OK) {
    loc.fail(data_pos, "cannot start bz2 decompression: " + bz2_error_name(rc));
  }
  struct End {
    bz_stream* stream;
    ~End() { BZ2_bzDecompressEnd(stream); }
  } end{&s};
  Inflated out(declared, data.size());
  s.next_in = reinterpret_cast<char*>(const_cast<uint8_t*>(data.data()));
  s.avail_in = static_cast<unsigned int>(data.size());
  for (;;) {
    const std::span<uint8_t> space = out.space();
    if (space.empty()) {
      loc.fail(data_pos,
               "bz2 chunk decompresses to more than the " + std::to_string(declared) + " bytes its header declares");
    }
    s.next_out = reinterpret_cast<char*>(space.data());
    s.avail_out = static_cast<unsigned int>(std::min<size_t>(space.size(), UINT32_MAX));
    const unsigned int avail_before = s.avail_out;
    const int rc = BZ2_bzDecompress(&s);
    out.produced(avail_before - s.avail_out);
    if (rc == BZ_STREAM_END) break;
    if (rc != BZ_OK) {
      loc.fail(data_pos + (data.size() - s.avail_in), "bz2 chunk data is corrupt: " + bz2_error_name(rc));
    }
    if (s.avail_in == 0 && s.avail_out > 0) {
      loc.fail(data_pos + data.size(), "bz2 chunk data ends before the end of its stream");
    }
  }
  if (s.avail_in != 0) {
    loc.fail(data_pos + (data.size() - s.avail_in),
             std::to_string(s.avail_in) + " bytes follow the end of the bz2 stream in the chunk");
  }
  if (out.used() != declared) {
    loc.fail(data_pos, "bz2 chunk decompresses to " + std::to_string(out.used()) + " bytes, its header declares " +
                           std::to_string(declared));
  }
  return out.take();
}

class Ros1BagReader final : public BagReader {
 public:
  explicit Ros1BagReader(const std::filesystem::path& path)
      : path_(path), file_(path), loc_{path.string(), std::nullopt} {
    read_bag_header();
    try {
      scan_records();
      check_index_section();
    } catch (const FormatError& e) {
      damage_ = e.what();
    }
    list_messages();
  }

  std::vector<BagTopic> topics() const override { return topics_; }

  bool next(BagMessage& out) override {
    if (failure_) throw FormatError(*failure_);
    if (next_ == entries_.size()) {
      if (damage_) {
        failure_ = damage_;
        throw FormatError(*failure_);
      }
      return false;
    }
    try {
      const Entry& e = entries_[next_];
      const Connection& conn = connections_.at(e.conn);
      out.topic = conn.topic;
      out.type = conn.type;
      out.log_time_ns = e.time_ns;
      out.serialization = Serialization::kRos1;
      if (e.chunk == kLooseMessage) {
        const Record r = read_record(FileBytes{file_}, e.source_pos, loc_);
        out.data = file_.read(r.data_pos, r.data_len, loc_);
      } else {
        LoadedChunk& chunk = loaded_chunk(e.chunk);
        const auto it = chunk.messages.find(e.offset);
        if (it == chunk.messages.end() || it->second.conn != e.conn || it->second.time_ns != e.time_ns) {
          Locator{loc_.path, chunks_[e.chunk].pos}.fail(
              e.offset, "the chunk's index lists a message here that the chunk does not hold");
        }
        if (it->second.taken) {
          Locator{loc_.path, chunks_[e.chunk].pos}.fail(e.offset, "the chunk's index lists this message twice");
        }
        it->second.taken = true;
        const auto begin = chunk.data.begin() + static_cast<std::ptrdiff_t>(it->second.data_pos);
        out.data.assign(begin, begin + it->second.data_len);
        if (--chunk.remaining == 0) loaded_.erase(e.chunk);
      }
    } catch (const FormatError& err) {
      failure_ = err.what();
      throw;
    }
    ++next_;
    return true;
  }

  std::string describe() const override { return "ROS 1 bag " + path_.string(); }

 private:
  struct Connection {
    std::string topic;
    std::string type;  // ROS 2 spelling
  };
  struct IndexEntry {
    int64_t time_ns;
    uint32_t conn;
    uint32_t offset;
  };
  struct Chunk {
    uint64_t pos = 0;  // start of the chunk record
    uint64_t data_pos = 0;
    uint32_t data_len = 0;
    uint32_t size = 0;  // uncompressed
    std::string compression;
    std::vector<IndexEntry> index;  // from the index data records after the chunk
    bool indexed = false;
  };
  // One message to yield: in chunk `chunk` at uncompressed offset `offset`, or (chunk ==
  // kLooseMessage) a message data record at file offset source_pos outside any chunk.
  struct Entry {
    int64_t time_ns;
    uint64_t source_pos;
    uint32_t offset;
    uint32_t conn;
    uint32_t chunk;
  };
  struct ChunkMessage {
    uint32_t conn;
    int64_t time_ns;
    uint64_t data_pos;
    uint32_t data_len;
    bool taken = false;
  };
  struct LoadedChunk {
    std::vector<uint8_t> data;
    std::unordered_map<uint64_t, ChunkMessage> messages;  // by offset of the message record
    uint64_t remaining = 0;                               // messages not yet yielded
  };

  void read_bag_header() {
    const uint64_t size = file_.size();
    if (size < kVersionLine.size()) {
      loc_.fail(0, "file of " + std::to_string(size) + " bytes is too short for the version line '#ROSBAG V2.0'");
    }
    const std::vector<uint8_t> version = file_.read(0, kVersionLine.size(), loc_);
    const std::string_view line(reinterpret_cast<const char*>(version.data()), version.size());
    if (line != kVersionLine) {
      if (line.starts_with("#ROSBAG V")) {
        loc_.fail(0, "unsupported ROS bag version '" + std::string(line.substr(0, line.find('\n'))) +
                         "' (this reader reads V2.0)");
      }
      loc_.fail(0, "not a ROS 1 bag: expected the version line '#ROSBAG V2.0'");
    }
    const Record r = read_record(FileBytes{file_}, kVersionLine.size(), loc_);
    if (r.op != kOpBagHeader) {
      loc_.fail(r.pos, "expected the bag header record (op 0x03), found op " + std::to_string(r.op));
    }
    if (r.header->has("encryptor") && !r.header->str("encryptor").empty()) {
      loc_.fail(r.pos, "encrypted bags are not supported");
    }
    index_pos_ = r.header->u64("index_pos");
    conn_count_ = r.header->u32("conn_count");
    chunk_count_ = r.header->u32("chunk_count");
    records_pos_ = r.end;
  }

  // Walks the top-level records after the bag header.
  void scan_records() {
    uint64_t pos = records_pos_;
    while (pos < file_.size()) {
      if (pos == index_pos_) index_pos_is_record_ = true;
      const Record r = read_record(FileBytes{file_}, pos, loc_);
      switch (r.op) {
        case kOpChunk:
          add_chunk(r);
          break;
        case kOpIndexData:
          add_index_data(r);
          break;
        case kOpConnection: {
          const std::vector<uint8_t> data = file_.read(r.data_pos, r.data_len, loc_);
          add_connection(*r.header, data, r.pos, r.data_pos, loc_);
          if (index_pos_ != 0 && r.pos >= index_pos_) ++index_connections_;
          break;
        }
        case kOpChunkInfo:
          add_chunk_info(r);
          break;
        case kOpMessageData:
          // An uncompressed chunk that was never closed: its records follow a chunk header of
          // size 0, so they appear at the top level.
          add_loose_message(r);
          break;
        case kOpBagHeader:
          loc_.fail(r.pos, "a second bag header record");
          break;
        default:
          loc_.fail(r.pos, "unknown record op " + std::to_string(r.op));
      }
      pos = r.end;
    }
    if (pos == index_pos_) index_pos_is_record_ = true;
  }

  void add_chunk(const Record& r) {
    Chunk c;
    c.pos = r.pos;
    c.data_pos = r.data_pos;
    c.data_len = r.data_len;
    c.size = r.header->u32("size");
    c.compression = r.header->str("compression");
    if (c.compression != "none" && c.compression != "bz2" && c.compression != "lz4") {
      loc_.fail(r.pos, "unsupported chunk compression '" + c.compression + "' (none, bz2 and lz4 are read)");
    }
    chunks_.push_back(std::move(c));
  }

  // Checks the record's format version (header field "ver") against the one this reader knows.
  void check_version(const Record& r, uint32_t expected, const char* record) const {
    const uint32_t version = r.header->u32("ver");
    if (version != expected) {
      loc_.fail(r.pos,
                std::string(record) + " version " + std::to_string(version) + ", expected " + std::to_string(expected));
    }
  }

  // The record's entry count (header field "count"), checked against its data length at
  // entry_bytes an entry.
  uint32_t entry_count(const Record& r, uint64_t entry_bytes, const char* data, const char* entries) const {
    const uint32_t count = r.header->u32("count");
    if (r.data_len != uint64_t{count} * entry_bytes) {
      loc_.fail(r.pos, std::string(data) + " of " + std::to_string(r.data_len) + " bytes for " + std::to_string(count) +
                           " " + entries + ", expected " + std::to_string(uint64_t{count} * entry_bytes));
    }
    return count;
  }

  void add_index_data(const Record& r) {
    if (chunks_.empty()) loc_.fail(r.pos, "index data record before any chunk");
    check_version(r, kIndexDataVersion, "index data");
    const uint32_t conn = r.header->u32("conn");
    const uint32_t count = entry_count(r, kIndexEntryBytes, "index data", "entries");
    const std::vector<uint8_t> data = file_.read(r.data_pos, r.data_len, loc_);
    Chunk& chunk = chunks_.back();
    for (uint64_t i = 0; i < count; ++i) {
      const uint8_t* p = data.data() + i * kIndexEntryBytes;
      chunk.index.push_back({load_time_ns(p), conn, load_u32(p + 8)});
    }
    chunk.indexed = true;
  }

  void add_chunk_info(const Record& r) {
    check_version(r, kChunkInfoVersion, "chunk info");
    const uint64_t chunk_pos = r.header->u64("chunk_pos");
    const uint32_t count = entry_count(r, kChunkInfoEntryBytes, "chunk info data", "connections");
    const std::vector<uint8_t> data = file_.read(r.data_pos, r.data_len, loc_);
    uint64_t messages = 0;
    for (uint64_t i = 0; i < count; ++i) messages += load_u32(data.data() + i * kChunkInfoEntryBytes + 4);
    chunk_infos_.push_back({r.pos, chunk_pos, messages});
  }

  void add_loose_message(const Record& r) {
    entries_.push_back({r.header->time_ns("time"), r.pos, 0, r.header->u32("conn"), kLooseMessage});
  }

  // A connection record: header {op, conn, topic}, data = fields {topic, type, md5sum, ...}.
  void add_connection(const Fields& header, std::span<const uint8_t> data, uint64_t record_pos, uint64_t data_pos,
                      const Locator& loc) {
    const uint32_t id = header.u32("conn");
    const Fields fields(data, data_pos, record_pos, loc);
    Connection c{header.str("topic"), detail::ros2_type_name(fields.str("type"))};
    const auto [it, inserted] = connections_.try_emplace(id, c);
    if (!inserted && (it->second.topic != c.topic || it->second.type != c.type)) {
      loc.fail(record_pos, "connection " + std::to_string(id) + " is " + c.topic + " (" + c.type + ") here but " +
                               it->second.topic + " (" + it->second.type + ") before");
    }
  }

  // With an index section (the bag was closed), it must be complete and agree with the chunks.
  void check_index_section() {
    if (index_pos_ == 0) return;  // not closed: the chunks are scanned
    const uint64_t size = file_.size();
    if (index_pos_ > size) {
      loc_.fail(size, "the file ends here but its bag header places the index section at byte " +
                          std::to_string(index_pos_) + " (truncated file)");
    }
    if (!index_pos_is_record_) {
      loc_.fail(index_pos_, "the bag header places the index section here, which is not a record start");
    }
    if (index_connections_ != conn_count_ || chunk_infos_.size() != chunk_count_) {
      loc_.fail(size, "the index section holds " + std::to_string(index_connections_) + " of " +
                          std::to_string(conn_count_) + " connection records and " +
                          std::to_string(chunk_infos_.size()) + " of " + std::to_string(chunk_count_) +
                          " chunk info records (truncated file?)");
    }
    if (chunk_infos_.size() != chunks_.size()) {
      loc_.fail(index_pos_, "the index section lists " + std::to_string(chunk_infos_.size()) +
                                " chunks, the file holds " + std::to_string(chunks_.size()));
    }
    for (size_t i = 0; i < chunks_.size(); ++i) {
      const ChunkInfo& info = chunk_infos_[i];
      if (info.chunk_pos != chunks_[i].pos) {
        loc_.fail(info.pos, "chunk info points at byte " + std::to_string(info.chunk_pos) + ", the chunk is at byte " +
                                std::to_string(chunks_[i].pos));
      }
      if (chunks_[i].indexed && info.messages != chunks_[i].index.size()) {
        loc_.fail(info.pos, "chunk info counts " + std::to_string(info.messages) +
                                " messages, the index data "
                                "after the chunk lists " +
                                std::to_string(chunks_[i].index.size()));
      }
    }
  }

  // Builds the time-ordered list of messages from the chunk indexes, scanning the chunks whose
  // index is missing or cannot be trusted (the last chunk before damage may have lost part of it).
  void list_messages() {
    for (size_t c = 0; c < chunks_.size(); ++c) {
      Chunk& chunk = chunks_[c];
      const bool last_before_damage = damage_.has_value() && c + 1 == chunks_.size();
      const bool index_usable = chunk.indexed && !last_before_damage &&
                                std::all_of(chunk.index.begin(), chunk.index.end(),
                                            [&](const IndexEntry& e) { return connections_.contains(e.conn); });
      const auto chunk_id = static_cast<uint32_t>(c);
      if (index_usable) {
        for (const IndexEntry& e : chunk.index) entries_.push_back({e.time_ns, chunk.pos, e.offset, e.conn, chunk_id});
        continue;
      }
      try {
        const LoadedChunk loaded = load_chunk(chunk_id);
        for (const auto& [offset, m] : loaded.messages) {
          entries_.push_back({m.time_ns, chunk.pos, static_cast<uint32_t>(offset), m.conn, chunk_id});
        }
        chunk.index.clear();
        chunk.indexed = false;
      } catch (const FormatError& e) {
        damage_ = e.what();  // earlier in the file than any damage found by the record scan
        const uint64_t damaged_pos = chunk.pos;
        chunks_.resize(c);
        drop_messages_after(damaged_pos);
        break;
      }
    }
    // Loose messages may use connections defined in chunks, so they are checked after the chunks
    // (they were listed first, in file order).
    const auto undefined = std::find_if(entries_.begin(), entries_.end(), [&](const Entry& e) {
      return e.chunk == kLooseMessage && !connections_.contains(e.conn);
    });
    if (undefined != entries_.end()) {
      const uint64_t pos = undefined->source_pos;
      damage_ = loc_.path + ": byte " + std::to_string(pos) + ": message on connection " +
                std::to_string(undefined->conn) + ", which no earlier record defines";
      drop_messages_after(pos - 1);
    }
    std::sort(entries_.begin(), entries_.end(), [](const Entry& a, const Entry& b) {
      return std::tie(a.time_ns, a.source_pos, a.offset) < std::tie(b.time_ns, b.source_pos, b.offset);
    });
    entries_per_chunk_.assign(chunks_.size(), 0);
    std::map<std::string, BagTopic> topics;
    for (const Entry& e : entries_) {
      if (e.chunk != kLooseMessage) ++entries_per_chunk_[e.chunk];
      const Connection& conn = connections_.at(e.conn);
      BagTopic& t = topics[conn.topic];
      if (t.name.empty()) t = {conn.topic, conn.type, 0, "ros1"};
      ++t.messages;
    }
    for (auto& [name, t] : topics) topics_.push_back(std::move(t));
  }

  // Damage at pos: the messages stored after it are not yielded.
  void drop_messages_after(uint64_t pos) {
    std::erase_if(entries_, [&](const Entry& x) { return x.source_pos > pos; });
  }

  LoadedChunk& loaded_chunk(uint32_t chunk_id) {
    auto it = loaded_.find(chunk_id);
    if (it != loaded_.end()) return it->second;
    LoadedChunk chunk = load_chunk(chunk_id);
    if (chunk.messages.size() != entries_per_chunk_[chunk_id]) {
      loc_.fail(chunks_[chunk_id].pos, "the chunk holds " + std::to_string(chunk.messages.size()) +
                                           " messages, its index lists " +
                                           std::to_string(entries_per_chunk_[chunk_id]));
    }
    chunk.remaining = entries_per_chunk_[chunk_id];
    return loaded_.emplace(chunk_id, std::move(chunk)).first->second;
  }

  // Decompresses a chunk and lists its message records; its connection records are learnt.
  LoadedChunk load_chunk(uint32_t chunk_id) {
    const Chunk& c = chunks_[chunk_id];
    LoadedChunk out;
    if (c.compression == "none") {
      if (c.data_len != c.size) {
        loc_.fail(c.pos, "uncompressed chunk of " + std::to_string(c.data_len) + " bytes, its header declares " +
                             std::to_string(c.size));
      }
      out.data = file_.read(c.data_pos, c.data_len, loc_);
    } else {
      if (c.data_len == 0) {
        loc_.fail(c.pos, c.compression + " chunk without data (the recording was not closed)");
      }
      const std::vector<uint8_t> compressed = file_.read(c.data_pos, c.data_len, loc_);
      if (c.compression == "bz2") {
        out.data = inflate_bz2(compressed, c.size, c.data_pos, loc_);
      } else {
        // ROS 1's lz4 chunks are LZ4 frames (magic 04 22 4D 18). The output may grow up to the
        // declared size, so a damaged size field costs no large allocation.
        const std::string where = loc_.path + ": byte " + std::to_string(c.data_pos) + ": lz4 chunk data";
        out.data = detail::lz4_decompress(compressed, std::nullopt, where, c.size);
        if (out.data.size() != c.size) {
          loc_.fail(c.data_pos, "lz4 chunk decompresses to " + std::to_string(out.data.size()) +
                                    " bytes, its header declares " + std::to_string(c.size));
        }
      }
    }
    const Locator loc{loc_.path, c.pos};
    const std::span<const uint8_t> buf(out.data);
    uint64_t pos = 0;
    while (pos < buf.size()) {
      const Record r = read_record(ChunkBytes{buf}, pos, loc);
      if (r.op == kOpConnection) {
        add_connection(*r.header, buf.subspan(r.data_pos, r.data_len), pos, r.data_pos, loc);
      } else if (r.op == kOpMessageData) {
        const uint32_t conn = r.header->u32("conn");
        if (!connections_.contains(conn)) {
          loc.fail(pos, "message on connection " + std::to_string(conn) + ", which no earlier record defines");
        }
        out.messages.emplace(pos, ChunkMessage{conn, r.header->time_ns("time"), r.data_pos, r.data_len});
      } else {
        loc.fail(pos, "unexpected record op " + std::to_string(r.op) + " inside a chunk");
      }
      pos = r.end;
    }
    return out;
  }

  struct ChunkInfo {
    uint64_t pos;        // of the chunk info record
    uint64_t chunk_pos;  // of the chunk it describes
    uint64_t messages;
  };

  std::filesystem::path path_;
  BagFile file_;
  Locator loc_;
  uint64_t index_pos_ = 0;
  uint32_t conn_count_ = 0;
  uint32_t chunk_count_ = 0;
  uint64_t records_pos_ = 0;
  bool index_pos_is_record_ = false;
  uint64_t index_connections_ = 0;
  std::vector<ChunkInfo> chunk_infos_;
  std::map<uint32_t, Connection> connections_;
  std::vector<Chunk> chunks_;
  std::vector<Entry> entries_;
  std::vector<uint64_t> entries_per_chunk_;
  std::vector<BagTopic> topics_;
  std::unordered_map<uint32_t, LoadedChunk> loaded_;
  size_t next_ = 0;
  std::optional<std::string> damage_;   // found while opening; reported after the intact messages
  std::optional<std::string> failure_;  // reported by every next() once thrown
};

}  // namespace

std::unique_ptr<BagReader> open_ros1_bag(const std::filesystem::path& path) {
  return std::make_unique<Ros1BagReader>(path);
}

}  // namespace cdc::io
