// open_bag(): recognises a bag by its content and hands it to the reader of its format. A ROS 2 bag
// folder (metadata.yaml beside its storage files) is read as all of its files merged in log-time order;
// rosbag2 compression (zstd per FILE or per MESSAGE) is undone here.
#include "cdc/io/bag.hpp"

#include "decompress.hpp"
#include "ros1_bag.hpp"
#include "ros2_bag.hpp"
#include "yaml_file.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>

namespace cdc::io {
namespace {

namespace fs = std::filesystem;
using detail::MessageCompression;

constexpr std::string_view kRos1Magic = "#ROSBAG V2.0\n";
constexpr std::string_view kRos1Prefix = "#ROSBAG V";
constexpr std::array<uint8_t, 16> kSqliteMagic{'S', 'Q', 'L', 'i', 't', 'e', ' ', 'f',
                                               'o', 'r', 'm', 'a', 't', ' ', '3', '\0'};
constexpr std::array<uint8_t, 8> kMcapMagic{0x89, 'M', 'C', 'A', 'P', '0', '\r', '\n'};
constexpr std::array<uint8_t, 4> kZstdMagic{0x28, 0xB5, 0x2F, 0xFD};

enum class Kind { kRos1, kSqlite, kMcap, kZstd, kUnknown };

template <size_t N>
bool starts_with(std::span<const uint8_t> head, const std::array<uint8_t, N>& magic) {
  return head.size() >= N && std::equal(magic.begin(), magic.end(), head.begin());
}
bool starts_with(std::span<const uint8_t> head, std::string_view magic) {
  return head.size() >= magic.size() && std::equal(magic.begin(), magic.end(), head.begin(),
                                                   [](char a, uint8_t b) { return static_cast<uint8_t>(a) == b; });
}

Kind kind_of(std::span<const uint8_t> head) {
  if (starts_with(head, kRos1Prefix)) return Kind::kRos1;
  if (starts_with(head, kSqliteMagic)) return Kind::kSqlite;
  if (starts_with(head, kMcapMagic)) return Kind::kMcap;
  if (starts_with(head, kZstdMagic)) return Kind::kZstd;
  return Kind::kUnknown;
}

std::vector<uint8_t> read_head(const fs::path& path, size_t n) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path.string() + ": cannot open for reading");
  std::vector<uint8_t> head(n);
  in.read(reinterpret_cast<char*>(head.data()), static_cast<std::streamsize>(n));
  head.resize(static_cast<size_t>(in.gcount()));
  return head;
}

std::vector<uint8_t> read_all(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path.string() + ": cannot open for reading");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::string printable_head(std::span<const uint8_t> head) {
  std::ostringstream s;
  s << std::hex;
  for (size_t i = 0; i < std::min<size_t>(head.size(), 8); ++i) s << (i ? " " : "") << int{head[i]};
  return s.str();
}

[[noreturn]] void unknown_format(const std::string& name, std::span<const uint8_t> head) {
  throw FormatError(name + ": not a bag: its first bytes (" + printable_head(head) +
                    ") match no known format (ROS 1 '#ROSBAG V2.0', SQLite 3 .db3, MCAP, zstd-compressed .db3/.mcap)");
}

// A storage file held in memory (decompressed): dispatched by its own magic.
std::unique_ptr<BagReader> open_bytes(std::vector<uint8_t> bytes, const std::string& name,
                                      MessageCompression compression) {
  switch (kind_of(bytes)) {
    case Kind::kSqlite:
      return detail::open_sqlite_bag_bytes(std::move(bytes), name, compression);
    case Kind::kMcap:
      return detail::open_mcap_bag_bytes(std::move(bytes), name);
    default:
      unknown_format(name + " (decompressed)", bytes);
  }
}

// One storage file, judged by content.
std::unique_ptr<BagReader> open_file(const fs::path& path, MessageCompression compression) {
  const auto head = read_head(path, 16);
  switch (kind_of(head)) {
    case Kind::kRos1:
      if (!starts_with(head, kRos1Magic)) {
        throw FormatError(path.string() + ": ROS 1 bag of an unsupported version (byte 0), only V2.0 is read");
      }
      return open_ros1_bag(path);
    case Kind::kSqlite:
      return detail::open_sqlite_bag(path, compression);
    case Kind::kMcap:
      return detail::open_mcap_bag(path);
    case Kind::kZstd:
      return open_bytes(detail::zstd_decompress(read_all(path), std::nullopt, path.string() + " (zstd file)"),
                        path.string(), compression);
    case Kind::kUnknown:
      break;
  }
  unknown_format(path.string(), head);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// What open_bag needs from a rosbag2 metadata.yaml.
struct Ros2Metadata {
  std::string storage;             // "sqlite3", "mcap" or empty
  std::vector<std::string> files;  // relative_file_paths
  MessageCompression message_compression = MessageCompression::kNone;
};

Ros2Metadata read_metadata(const fs::path& yaml_path) {
  const std::string name = yaml_path.string();
  const YAML::Node root = detail::load_yaml_file(name);
  const YAML::Node info = root["rosbag2_bagfile_information"];
  if (!info.IsMap()) throw FormatError(name + ": no 'rosbag2_bagfile_information' map at the top level");
  auto scalar = [&](const char* key) -> std::string {
    const YAML::Node n = info[key];
    if (!n || n.IsNull()) return {};
    if (!n.IsScalar()) {
      throw FormatError(name + ": line " + std::to_string(n.Mark().line + 1) + ": '" + key + "' is not a scalar");
    }
    return n.Scalar();
  };
  Ros2Metadata m;
  m.storage = scalar("storage_identifier");
  const std::string format = lower(scalar("compression_format"));
  const std::string mode = lower(scalar("compression_mode"));
  if (!format.empty() && format != "zstd") {
    throw FormatError(name + ": compression_format '" + format + "' is not supported (only zstd)");
  }
  if (format == "zstd" && mode == "message") m.message_compression = MessageCompression::kZstd;
  const YAML::Node paths = info["relative_file_paths"];
  if (paths && paths.IsSequence()) {
    for (const auto& p : paths) {
      if (!p.IsScalar()) {
        throw FormatError(name + ": line " + std::to_string(p.Mark().line + 1) +
                          ": a relative_file_paths entry is not a string");
      }
      m.files.push_back(p.Scalar());
    }
  }
  if (m.files.empty()) {
    const YAML::Node files = info["files"];
    if (files && files.IsSequence()) {
      for (const auto& f : files) {
        if (f.IsMap() && f["path"] && f["path"].IsScalar()) m.files.push_back(f["path"].Scalar());
      }
    }
  }
  if (m.files.empty()) throw FormatError(name + ": lists no storage files (relative_file_paths)");
  return m;
}

// Yields the messages of several readers in log-time order.
class MergedBag final : public BagReader {
 public:
  MergedBag(std::vector<std::unique_ptr<BagReader>> parts, std::string description)
      : parts_(std::move(parts)), pending_(parts_.size()), description_(std::move(description)) {}

  std::vector<BagTopic> topics() const override {
    std::vector<BagTopic> out;
    for (const auto& part : parts_) {
      for (const auto& t : part->topics()) {
        auto it = std::find_if(out.begin(), out.end(), [&](const BagTopic& o) {
          return o.name == t.name && o.type == t.type && o.encoding == t.encoding;
        });
        if (it == out.end()) {
          out.push_back(t);
        } else {
          it->messages += t.messages;
        }
      }
    }
    return out;
  }

  bool next(BagMessage& out) override {
    if (!primed_) {
      for (size_t i = 0; i < parts_.size(); ++i) refill(i);
      primed_ = true;
    }
    std::optional<size_t> best;
    for (size_t i = 0; i < pending_.size(); ++i) {
      if (pending_[i] && (!best || pending_[i]->log_time_ns < pending_[*best]->log_time_ns)) best = i;
    }
    if (!best) return false;
    out = std::move(*pending_[*best]);
    refill(*best);
    return true;
  }

  std::string describe() const override { return description_; }

 private:
  void refill(size_t i) {
    BagMessage m;
    if (parts_[i]->next(m)) {
      pending_[i] = std::move(m);
    } else {
      pending_[i].reset();
    }
  }

  std::vector<std::unique_ptr<BagReader>> parts_;
  std::vector<std::optional<BagMessage>> pending_;
  std::string description_;
  bool primed_ = false;
};

std::unique_ptr<BagReader> open_ros2_folder(const fs::path& dir) {
  const fs::path yaml = dir / "metadata.yaml";
  std::vector<fs::path> files;
  MessageCompression compression = MessageCompression::kNone;
  std::string storage;
  if (fs::exists(yaml)) {
    const Ros2Metadata m = read_metadata(yaml);
    compression = m.message_compression;
    storage = m.storage;
    for (const auto& rel : m.files) {
      // Early rosbag2 versions wrote paths that include the bag folder's own name.
      fs::path p = dir / rel;
      if (!fs::exists(p) && fs::exists(dir / fs::path(rel).filename())) p = dir / fs::path(rel).filename();
      if (!fs::exists(p)) {
        throw FormatError(yaml.string() + ": lists storage file '" + rel + "', which is not in " + dir.string());
      }
      files.push_back(p);
    }
  } else {
    // A folder without metadata.yaml (e.g. a recording that never closed): its storage files by name.
    for (const auto& e : fs::directory_iterator(dir)) {
      const std::string ext = e.path().extension().string();
      if (e.is_regular_file() && (ext == ".db3" || ext == ".mcap")) files.push_back(e.path());
    }
    std::sort(files.begin(), files.end());
    if (files.empty()) {
      throw FormatError(dir.string() +
                        ": a directory with neither metadata.yaml nor .db3/.mcap files is not a ROS 2 bag");
    }
    storage = "by file content";
  }
  std::vector<std::unique_ptr<BagReader>> parts;
  for (const auto& f : files) parts.push_back(open_file(f, compression));
  const std::string description = "rosbag2 folder " + dir.string() + " (" + std::to_string(parts.size()) + " " +
                                  (storage.empty() ? "storage" : storage) + " file" + (parts.size() == 1 ? "" : "s") +
                                  ")";
  return detail::merge_bags(std::move(parts), description);
}

// The per-message compression a file's folder declares, when the file is opened on its own.
MessageCompression sibling_message_compression(const fs::path& file) {
  const fs::path yaml = file.parent_path() / "metadata.yaml";
  if (!fs::exists(yaml)) return MessageCompression::kNone;
  try {
    return read_metadata(yaml).message_compression;
  } catch (const FormatError&) {
    return MessageCompression::kNone;  // the file itself is what was asked for
  }
}

}  // namespace

namespace detail {

std::unique_ptr<BagReader> merge_bags(std::vector<std::unique_ptr<BagReader>> parts, std::string description) {
  return std::make_unique<MergedBag>(std::move(parts), std::move(description));
}

std::string ros2_type_name(std::string_view type) {
  const size_t slash = type.find('/');
  if (slash == std::string_view::npos || type.find('/', slash + 1) != std::string_view::npos) {
    return std::string(type);
  }
  return std::string(type.substr(0, slash)) + "/msg/" + std::string(type.substr(slash + 1));
}

}  // namespace detail

std::unique_ptr<BagReader> open_bag(const fs::path& path) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (ec || !fs::exists(st)) throw FormatError(path.string() + ": no such file or directory");
  if (fs::is_directory(st)) return open_ros2_folder(path);
  if (path.filename() == "metadata.yaml") {
    return open_ros2_folder(path.has_parent_path() ? path.parent_path() : fs::path("."));
  }
  return open_file(path, sibling_message_compression(path));
}

}  // namespace cdc::io
