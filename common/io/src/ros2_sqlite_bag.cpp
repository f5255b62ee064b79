// rosbag2 sqlite3 storage: tables topics(id, name, type, serialization_format, ...) and
// messages(id, topic_id, timestamp, data), read with libsqlite3, messages ordered by timestamp.
//
// Before SQLite sees the file, its 100-byte header is checked against the file size, so that a
// truncated copy is reported as such (SQLite itself would read the missing pages as zeros and report
// corruption somewhere later). Files are opened immutable (no lock or journal files, so read-only
// folders work) unless a write-ahead log lies beside them.
#include "ros2_bag.hpp"

#include "decompress.hpp"

#include <sqlite3.h>

#include <array>
#include <fstream>
#include <map>
#include <memory>

namespace cdc::io::detail {
namespace {

namespace fs = std::filesystem;

constexpr std::array<char, 16> kSqliteMagic{'S', 'Q', 'L', 'i', 't', 'e', ' ', 'f',
                                            'o', 'r', 'm', 'a', 't', ' ', '3', '\0'};
constexpr size_t kSqliteHeaderBytes = 100;

uint32_t be32(const uint8_t* p) {
  return (uint32_t{p[0]} << 24) | (uint32_t{p[1]} << 16) | (uint32_t{p[2]} << 8) | uint32_t{p[3]};
}

// Checks the database header (first 100 bytes) against the size of the whole database.
void check_sqlite_header(const uint8_t* header, size_t header_size, uint64_t file_size, const std::string& name) {
  if (header_size < kSqliteMagic.size() ||
      !std::equal(kSqliteMagic.begin(), kSqliteMagic.end(), reinterpret_cast<const char*>(header))) {
    throw FormatError(name + ": not an SQLite 3 database (byte 0: no 'SQLite format 3' header)");
  }
  if (header_size < kSqliteHeaderBytes) {
    throw FormatError(name + ": truncated: " + std::to_string(header_size) +
                      " bytes, fewer than the 100-byte SQLite header");
  }
  const uint32_t raw_page = (uint32_t{header[16]} << 8) | uint32_t{header[17]};
  const uint64_t page_size = raw_page == 1 ? 65536 : raw_page;
  if (page_size < 512 || (page_size & (page_size - 1)) != 0) {
    throw FormatError(name + ": SQLite header (byte 16) gives page size " + std::to_string(page_size) +
                      ", not a power of two from 512 to 65536");
  }
  if (file_size % page_size != 0) {
    throw FormatError(name + ": truncated: " + std::to_string(file_size) + " bytes is not a whole number of " +
                      std::to_string(page_size) + "-byte pages (the last page ends at byte " +
                      std::to_string(file_size / page_size * page_size) + ")");
  }
  // The in-header page count (byte 28) is valid when the change counter (byte 24) equals the
  // version-valid-for number (byte 92).
  const uint32_t pages = be32(header + 28);
  if (pages != 0 && be32(header + 24) == be32(header + 92) && uint64_t{pages} * page_size > file_size) {
    throw FormatError(name + ": truncated: the SQLite header (byte 28) declares " + std::to_string(pages) +
                      " pages of " + std::to_string(page_size) + " bytes (" +
                      std::to_string(uint64_t{pages} * page_size) + " bytes), the file has " +
                      std::to_string(file_size));
  }
}

// A URI for sqlite3_open_v2 naming a local file; characters with a meaning in URIs are escaped.
std::string file_uri(const fs::path& path, bool immutable) {
  std::string uri = "file:";
  for (const char ch : fs::absolute(path).string()) {
    if (ch == '%' || ch == '?' || ch == '#') {
      static const char* digits = "0123456789ABCDEF";
      const auto u = static_cast<unsigned char>(ch);
      uri += '%';
      uri += digits[u >> 4];
      uri += digits[u & 15];
    } else {
      uri += ch;
    }
  }
  return uri + (immutable ? "?mode=ro&immutable=1" : "?mode=ro");
}

struct TopicInfo {
  std::string name, type, encoding;
  bool supported = false;
  Serialization serialization = Serialization::kCdr;
  uint64_t messages = 0;
};

class SqliteBag final : public BagReader {
 public:
  // Opens the file at path, or (path empty) the database held in `bytes`.
  SqliteBag(const fs::path& path, std::vector<uint8_t> bytes, std::string name, MessageCompression compression)
      : bytes_(std::move(bytes)), name_(std::move(name)), compression_(compression) {
    if (!path.empty()) {
      open_file(path);
    } else {
      open_bytes();
    }
    read_topics();
    prepare_messages();
  }

  std::vector<BagTopic> topics() const override {
    std::vector<BagTopic> out;
    for (const auto& [id, t] : topics_) out.push_back(BagTopic{t.name, t.type, t.messages, t.encoding});
    return out;
  }

  bool next(BagMessage& out) override {
    while (true) {
      if (done_) return false;
      const int rc = sqlite3_step(stmt_.get());
      if (rc == SQLITE_DONE) {
        done_ = true;
        return false;
      }
      if (rc != SQLITE_ROW) {
        done_ = true;
        fail("SQLite error reading message row " + std::to_string(row_) +
             " (in timestamp order): " + sqlite3_errmsg(db_.get()));
      }
      const int64_t timestamp = sqlite3_column_int64(stmt_.get(), 0);
      const int64_t topic_id = sqlite3_column_int64(stmt_.get(), 1);
      const auto* blob = static_cast<const uint8_t*>(sqlite3_column_blob(stmt_.get(), 2));
      const int size = sqlite3_column_bytes(stmt_.get(), 2);
      const int64_t id = sqlite3_column_int64(stmt_.get(), 3);
      ++row_;
      auto it = topics_.find(topic_id);
      if (it == topics_.end()) {
        fail("message id " + std::to_string(id) + " refers to topic_id " + std::to_string(topic_id) +
             ", which the topics table lacks");
      }
      if (!it->second.supported) continue;
      out.topic = it->second.name;
      out.type = it->second.type;
      out.log_time_ns = timestamp;
      out.serialization = it->second.serialization;
      const std::span<const uint8_t> data(blob, blob == nullptr ? 0 : static_cast<size_t>(size));
      if (compression_ == MessageCompression::kZstd) {
        out.data = zstd_decompress(data, std::nullopt, name_ + ": message id " + std::to_string(id) + " (zstd)");
      } else {
        out.data.assign(data.begin(), data.end());
      }
      return true;
    }
  }

  std::string describe() const override { return "rosbag2 sqlite3 file " + name_; }

 private:
  [[noreturn]] void fail(const std::string& what) const { throw FormatError(name_ + ": " + what); }

  void open_file(const fs::path& path) {
    std::error_code ec;
    const uint64_t size = fs::file_size(path, ec);
    if (ec) fail("cannot read: " + ec.message());
    std::array<uint8_t, kSqliteHeaderBytes> header{};
    std::ifstream in(path, std::ios::binary);
    in.read(reinterpret_cast<char*>(header.data()), static_cast<std::streamsize>(header.size()));
    check_sqlite_header(header.data(), static_cast<size_t>(in.gcount()), size, name_);
    const bool wal = fs::exists(fs::path(path.string() + "-wal"));
    const std::string uri = file_uri(path, !wal);
    sqlite3* db = nullptr;
    const int rc = sqlite3_open_v2(uri.c_str(), &db, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, nullptr);
    db_.reset(db);
    if (rc != SQLITE_OK) {
      fail(std::string("SQLite cannot open the database: ") + (db ? sqlite3_errmsg(db) : "out of memory"));
    }
  }

  void open_bytes() {
    check_sqlite_header(bytes_.data(), bytes_.size(), bytes_.size(), name_);
    sqlite3* db = nullptr;
    const int open_rc = sqlite3_open_v2(":memory:", &db, SQLITE_OPEN_READWRITE, nullptr);
    db_.reset(db);
    if (open_rc != SQLITE_OK) fail("SQLite cannot open an in-memory database");
    const int rc = sqlite3_deserialize(db, "main", bytes_.data(), static_cast<sqlite3_int64>(bytes_.size()),
                                       static_cast<sqlite3_int64>(bytes_.size()), SQLITE_DESERIALIZE_READONLY);
    if (rc != SQLITE_OK) fail(std::string("SQLite cannot load the database: ") + sqlite3_errmsg(db));
  }

  void read_topics() {
    sqlite3_stmt* st = nullptr;
    const char* sql = "SELECT id, name, type, serialization_format FROM topics";
    if (sqlite3_prepare_v2(db_.get(), sql, -1, &st, nullptr) != SQLITE_OK) {
      const std::string msg = sqlite3_errmsg(db_.get());
      sqlite3_finalize(st);
      fail("not a rosbag2 database (reading its topics table: " + msg + ")");
    }
    int rc = SQLITE_ROW;
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
      TopicInfo t;
      const int64_t id = sqlite3_column_int64(st, 0);
      t.name = column_text(st, 1);
      t.type = ros2_type_name(column_text(st, 2));
      // Some recorders leave serialization_format empty although the data are CDR.
      t.encoding = column_text(st, 3);
      if (t.encoding.empty()) t.encoding = "cdr";
      t.supported = t.encoding == "cdr" || t.encoding == "ros1";
      t.serialization = t.encoding == "ros1" ? Serialization::kRos1 : Serialization::kCdr;
      topics_[id] = std::move(t);
    }
    if (rc != SQLITE_DONE) {
      const std::string msg = sqlite3_errmsg(db_.get());
      sqlite3_finalize(st);
      fail("SQLite error reading the topics table: " + msg);
    }
    sqlite3_finalize(st);
    // Message counts per topic (the metadata.yaml beside the file may be stale after a crash).
    st = nullptr;
    if (sqlite3_prepare_v2(db_.get(), "SELECT topic_id, COUNT(*) FROM messages GROUP BY topic_id", -1, &st, nullptr) !=
        SQLITE_OK) {
      const std::string msg = sqlite3_errmsg(db_.get());
      sqlite3_finalize(st);
      fail("not a rosbag2 database (reading its messages table: " + msg + ")");
    }
    while ((rc = sqlite3_step(st)) == SQLITE_ROW) {
      auto it = topics_.find(sqlite3_column_int64(st, 0));
      if (it != topics_.end()) it->second.messages = static_cast<uint64_t>(sqlite3_column_int64(st, 1));
    }
    if (rc != SQLITE_DONE) {
      const std::string msg = sqlite3_errmsg(db_.get());
      sqlite3_finalize(st);
      fail("SQLite error counting the messages: " + msg);
    }
    sqlite3_finalize(st);
  }

  void prepare_messages() {
    const char* sql = "SELECT timestamp, topic_id, data, id FROM messages ORDER BY timestamp, id";
    sqlite3_stmt* st = nullptr;
    const int rc = sqlite3_prepare_v2(db_.get(), sql, -1, &st, nullptr);
    stmt_.reset(st);
    if (rc != SQLITE_OK) fail(std::string("SQLite cannot query the messages: ") + sqlite3_errmsg(db_.get()));
  }

  static std::string column_text(sqlite3_stmt* st, int col) {
    const auto* text = sqlite3_column_text(st, col);
    return text == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(text));
  }

  std::vector<uint8_t> bytes_;  // the database when it is held in memory
  std::string name_;
  MessageCompression compression_;
  // stmt_ is declared after db_, so it is finalised before the database closes.
  std::unique_ptr<sqlite3, decltype(&sqlite3_close)> db_{nullptr, sqlite3_close};
  std::unique_ptr<sqlite3_stmt, decltype(&sqlite3_finalize)> stmt_{nullptr, sqlite3_finalize};
  std::map<int64_t, TopicInfo> topics_;
  uint64_t row_ = 0;
  bool done_ = false;
};

}  // namespace

std::unique_ptr<BagReader> open_sqlite_bag(const fs::path& path, MessageCompression compression) {
  return std::make_unique<SqliteBag>(path, std::vector<uint8_t>{}, path.string(), compression);
}

std::unique_ptr<BagReader> open_sqlite_bag_bytes(std::vector<uint8_t> bytes, const std::string& name,
                                                 MessageCompression compression) {
  return std::make_unique<SqliteBag>(fs::path{}, std::move(bytes), name, compression);
}

}  // namespace cdc::io::detail
