// The PCD reader: header checked entry by entry, data of each kind decoded with every size checked.
#include "pcd.hpp"

#include "cdc/io/error.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <string_view>

namespace cdc::io::detail {
namespace fs = std::filesystem;

namespace {

// The header's entries in the order the format prescribes; VERSION, COUNT and VIEWPOINT are optional.
constexpr std::array<std::string_view, 10> kPcdKeys{"VERSION", "FIELDS", "SIZE",      "TYPE",   "COUNT",
                                                    "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
constexpr size_t kRequired[] = {1, 2, 3, 5, 6, 8};  // FIELDS SIZE TYPE WIDTH HEIGHT POINTS
constexpr uint64_t kMaxPointStep = uint64_t{1} << 20;
constexpr uint64_t kMaxCloudBytes = (uint64_t{1} << 32) - 1;  // a PointCloud2's row_step is 32 bits

struct PcdField {
  std::string name;
  uint32_t size = 0;  // bytes of one value
  char type = 0;      // I, U or F
  uint32_t count = 1;
  uint32_t offset = 0;
  uint32_t bytes() const { return size * count; }
};

struct PcdHeader {
  std::vector<PcdField> fields;
  uint64_t points = 0;
  uint64_t point_step = 0;
  std::string kind;        // ascii, binary or binary_compressed
  size_t data_offset = 0;  // first byte after the DATA line
  size_t data_line = 0;    // the DATA line's number
};

std::vector<std::string> words_of(std::string_view line) {
  std::istringstream in{std::string(line)};
  return {std::istream_iterator<std::string>(in), std::istream_iterator<std::string>()};
}

uint64_t parse_count(const std::string& where, std::string_view key, const std::string& text, uint64_t max) {
  uint64_t v = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), v);
  if (ec != std::errc() || end != text.data() + text.size() || v > max) {
    throw FormatError(where + std::string(key) + " value '" + text + "' is not a count up to " + std::to_string(max));
  }
  return v;
}

// Applies one entry's values (their number and kind checked) to the header.
void apply_entry(PcdHeader& h, std::string_view key, const std::vector<std::string>& values, const std::string& where) {
  if (key == "FIELDS") {
    if (values.empty()) throw FormatError(where + "FIELDS names no field");
    for (const std::string& name : values) h.fields.push_back({name});
    return;
  }
  if (key == "SIZE" || key == "TYPE" || key == "COUNT") {
    if (values.size() != h.fields.size()) {
      throw FormatError(where + std::string(key) + " has " + std::to_string(values.size()) + " values for " +
                        std::to_string(h.fields.size()) + " fields");
    }
    for (size_t i = 0; i < values.size(); ++i) {
      PcdField& f = h.fields[i];
      if (key == "SIZE") {
        f.size = static_cast<uint32_t>(parse_count(where, key, values[i], 8));
        if (f.size != 1 && f.size != 2 && f.size != 4 && f.size != 8)
          throw FormatError(where + "SIZE of field '" + f.name + "' is " + values[i] + ", not 1, 2, 4 or 8");
      } else if (key == "TYPE") {
        if (values[i] != "I" && values[i] != "U" && values[i] != "F")
          throw FormatError(where + "TYPE of field '" + f.name + "' is '" + values[i] + "', not I, U or F");
        f.type = values[i][0];
      } else {
        f.count = static_cast<uint32_t>(parse_count(where, key, values[i], kMaxPointStep));
        if (f.count == 0) throw FormatError(where + "COUNT of field '" + f.name + "' is 0");
      }
    }
    return;
  }
  if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
    if (values.size() != 1) throw FormatError(where + std::string(key) + " needs one value");
    const uint64_t v = parse_count(where, key, values[0], kMaxCloudBytes);
    if (key == "POINTS") h.points = v;
    return;
  }
  if (key == "DATA") {
    if (values.size() != 1 || (values[0] != "ascii" && values[0] != "binary" && values[0] != "binary_compressed")) {
      throw FormatError(where + "DATA must be ascii, binary or binary_compressed");
    }
    h.kind = values[0];
  }
}

// Field offsets and the point step, once the header is complete.
void lay_out_fields(PcdHeader& h, const std::string& where) {
  uint64_t step = 0;
  for (PcdField& f : h.fields) {
    if (f.type == 'F' && f.size != 4 && f.size != 8)
      throw FormatError(where + "field '" + f.name + "' is a float of " + std::to_string(f.size) + " bytes");
    f.offset = static_cast<uint32_t>(step);
    step += uint64_t{f.size} * f.count;
    if (step > kMaxPointStep) throw FormatError(where + "points of over " + std::to_string(kMaxPointStep) + " bytes");
  }
  h.point_step = step;
  if (h.points * step > kMaxCloudBytes) {
    throw FormatError(where + std::to_string(h.points) + " points of " + std::to_string(step) +
                      " bytes is not a plausible cloud");
  }
}

// The header up to and including the DATA line: each entry at most once and in the prescribed order,
// the required ones present, as many SIZE, TYPE and COUNT values as FIELDS, and a known DATA kind.
PcdHeader parse_header(const fs::path& path, std::string_view bytes) {
  PcdHeader h;
  size_t next = 0;  // index in kPcdKeys the next entry may have
  size_t pos = 0;
  for (size_t n = 1; pos < bytes.size(); ++n) {
    const size_t eol = std::min(bytes.find('\n', pos), bytes.size());
    const std::string_view line = bytes.substr(pos, eol - pos);
    pos = eol + 1;
    std::vector<std::string> values = words_of(line);
    if (values.empty() || values[0][0] == '#') continue;
    const std::string key = values[0];
    values.erase(values.begin());
    const auto* it = std::find(kPcdKeys.begin(), kPcdKeys.end(), key);
    const auto at = static_cast<size_t>(it - kPcdKeys.begin());
    const std::string where = path.string() + ":" + std::to_string(n) + ": ";
    if (it == kPcdKeys.end()) throw FormatError(where + "'" + key + "' is not a PCD header entry");
    if (at < next) throw FormatError(where + key + " repeated or out of the PCD header's order");
    for (size_t k : kRequired) {
      if (k >= next && k < at) throw FormatError(where + std::string(kPcdKeys[k]) + " missing before " + key);
    }
    next = at + 1;
    apply_entry(h, key, values, where);
    if (key == "DATA") {
      lay_out_fields(h, where);
      h.data_offset = std::min(pos, bytes.size());
      h.data_line = n;
      return h;
    }
  }
  throw FormatError(path.string() + ": PCD header without DATA");
}

// One ascii value of field f written at `out` in the field's binary type.
bool put_value(const PcdField& f, std::string_view text, uint8_t* out) {
  if (!text.empty() && text[0] == '+') text.remove_prefix(1);
  const char* first = text.data();
  const char* last = first + text.size();
  if (f.type == 'F') {
    double v = 0;
    const auto [end, ec] = std::from_chars(first, last, v);
    if (ec != std::errc() || end != last) return false;
    const float v32 = static_cast<float>(v);
    f.size == 4 ? std::memcpy(out, &v32, 4) : std::memcpy(out, &v, 8);
    return true;
  }
  const unsigned bits = 8 * f.size;
  if (f.type == 'U') {
    uint64_t v = 0;
    const auto [end, ec] = std::from_chars(first, last, v);
    if (ec != std::errc() || end != last || (bits < 64 && v >> bits != 0)) return false;
    std::memcpy(out, &v, f.size);  // little-endian: the low bytes
    return true;
  }
  int64_t v = 0;
  const auto [end, ec] = std::from_chars(first, last, v);
  const int64_t lim = bits < 64 ? int64_t{1} << (bits - 1) : 0;
  if (ec != std::errc() || end != last || (bits < 64 && (v < -lim || v >= lim))) return false;
  std::memcpy(out, &v, f.size);
  return true;
}

// ascii data: one point per line, the fields' values in order; blank lines skipped.
std::vector<uint8_t> ascii_data(const fs::path& path, const PcdHeader& h, std::string_view text) {
  uint64_t per_point = 0;
  for (const PcdField& f : h.fields) per_point += f.count;
  if (h.points * per_point > text.size()) {
    throw FormatError(path.string() + ": ascii data of " + std::to_string(text.size()) + " bytes cannot hold " +
                      std::to_string(h.points) + " points");
  }
  std::vector<uint8_t> data(h.points * h.point_step);
  uint64_t point = 0;
  size_t pos = 0;
  for (size_t n = h.data_line + 1; pos < text.size(); ++n) {
    const size_t eol = std::min(text.find('\n', pos), text.size());
    const std::vector<std::string> values = words_of(text.substr(pos, eol - pos));
    pos = eol + 1;
    if (values.empty()) continue;
    const std::string where = path.string() + ":" + std::to_string(n) + ": ";
    if (point == h.points) throw FormatError(where + "more points than POINTS " + std::to_string(h.points));
    if (values.size() != per_point) {
      throw FormatError(where + std::to_string(values.size()) + " values, the fields need " +
                        std::to_string(per_point));
    }
    size_t v = 0;
    for (const PcdField& f : h.fields) {
      for (uint32_t c = 0; c < f.count; ++c, ++v) {
        if (!put_value(f, values[v], &data[point * h.point_step + f.offset + c * f.size])) {
          throw FormatError(where + "'" + values[v] + "' is not a value of field '" + f.name + "' (" + f.type +
                            std::to_string(f.size) + ")");
        }
      }
    }
    ++point;
  }
  if (point != h.points) {
    throw FormatError(path.string() + ": ascii data holds " + std::to_string(point) + " points, POINTS is " +
                      std::to_string(h.points));
  }
  return data;
}

// binary_compressed data: compressed and uncompressed sizes (uint32 each), then LZF data that decodes
// to the fields one after the other, each field's values for all points together.
std::vector<uint8_t> compressed_data(const fs::path& path, const PcdHeader& h, std::span<const uint8_t> rest) {
  const uint64_t point_bytes = h.points * h.point_step;
  uint32_t sizes[2] = {0, 0};  // compressed, uncompressed
  if (rest.size() >= 8) std::memcpy(sizes, rest.data(), 8);
  if (rest.size() < 8 || sizes[0] > rest.size() - 8 || sizes[1] != point_bytes) {
    throw FormatError(path.string() + ": compressed data does not match the header's points and fields");
  }
  const std::vector<uint8_t> columns =
      lzf_decode(rest.subspan(8, sizes[0]), point_bytes, path.string() + ": ", h.data_offset + 8);
  std::vector<uint8_t> data(point_bytes);
  uint64_t column = 0;
  for (const PcdField& f : h.fields) {
    const uint32_t w = f.bytes();
    for (uint64_t p = 0; p < h.points; ++p) {
      std::memcpy(&data[p * h.point_step + f.offset], &columns[column + p * w], w);
    }
    column += h.points * w;
  }
  return data;
}

uint8_t datatype_of(const PcdField& f) {
  switch (f.size) {
    case 1:
      return f.type == 'I' ? 1 : f.type == 'U' ? 2 : 0;
    case 2:
      return f.type == 'I' ? 3 : f.type == 'U' ? 4 : 0;
    case 4:
      return f.type == 'I' ? 5 : f.type == 'U' ? 6 : 7;
    default:
      return f.type == 'F' ? 8 : 0;  // no PointCloud2 code for 8-byte integers
  }
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw FormatError(path.string() + ": cannot open");
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

std::vector<uint8_t> lzf_decode(std::span<const uint8_t> in, uint64_t expected, const std::string& where,
                                uint64_t base) {
  // A 3-byte back-reference yields at most 264 bytes: no more than that can be expected of the input.
  if (expected / 88 > in.size()) {
    throw FormatError(where + "LZF data of " + std::to_string(in.size()) + " bytes cannot decode to " +
                      std::to_string(expected));
  }
  std::vector<uint8_t> out;
  out.reserve(expected);
  size_t i = 0;
  auto fail = [&](const std::string& what) {
    throw FormatError(where + "LZF data at byte " + std::to_string(base + i) + ": " + what);
  };
  while (i < in.size()) {
    const unsigned ctrl = in[i];
    size_t len = ctrl >> 5;  // 0: a literal run of ctrl + 1 bytes, else a back-reference of len + 2 bytes
    size_t need = len == 0 ? ctrl + 1 : len == 7 ? 2 : 1;
    if (need > in.size() - i - 1) fail("truncated");
    if (len == 0) {
      if (need > expected - out.size()) fail("decodes to more than " + std::to_string(expected) + " bytes");
      out.insert(out.end(), in.begin() + static_cast<std::ptrdiff_t>(i + 1),
                 in.begin() + static_cast<std::ptrdiff_t>(i + 1 + need));
      i += 1 + need;
      continue;
    }
    if (len == 7) len += in[i + 1];
    len += 2;
    const size_t distance = ((size_t{ctrl} & 0x1f) << 8) + in[i + need] + 1;
    if (distance > out.size()) fail("refers to " + std::to_string(distance) + " bytes back, before the start");
    if (len > expected - out.size()) fail("decodes to more than " + std::to_string(expected) + " bytes");
    for (size_t k = 0; k < len; ++k) out.push_back(out[out.size() - distance]);
    i += 1 + need;
  }
  if (out.size() != expected) {
    throw FormatError(where + "LZF data decodes to " + std::to_string(out.size()) + " bytes, not " +
                      std::to_string(expected));
  }
  return out;
}

PointCloud2Msg read_pcd(const fs::path& path) {
  const std::string bytes = read_bytes(path);
  const PcdHeader h = parse_header(path, bytes);
  const std::string_view rest = std::string_view(bytes).substr(h.data_offset);
  PointCloud2Msg m;
  m.height = 1;
  m.width = static_cast<uint32_t>(h.points);
  m.point_step = static_cast<uint32_t>(h.point_step);
  m.row_step = static_cast<uint32_t>(h.points * h.point_step);
  for (const PcdField& f : h.fields) m.fields.push_back({f.name, f.offset, datatype_of(f), f.count});
  if (h.kind == "ascii") {
    m.data = ascii_data(path, h, rest);
  } else if (h.kind == "binary") {
    if (rest.size() < m.row_step) {
      throw FormatError(path.string() + ": binary data of " + std::to_string(rest.size()) +
                        " bytes, the header announces " + std::to_string(m.row_step));
    }
    m.data.assign(rest.begin(), rest.begin() + m.row_step);
  } else {
    m.data = compressed_data(path, h, {reinterpret_cast<const uint8_t*>(rest.data()), rest.size()});
  }
  return m;
}

}  // namespace cdc::io::detail
