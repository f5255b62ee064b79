#include "cdc/dds/compact.hpp"

#include <zlib.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace cdc::dds::compact {

std::vector<uint8_t> deflate_bytes(const uint8_t* data, size_t n) {
  uLongf size = compressBound(static_cast<uLong>(n));
  std::vector<uint8_t> out(size);
  if (compress2(out.data(), &size, data, static_cast<uLong>(n), Z_BEST_COMPRESSION) != Z_OK) {
    // Only possible on allocation failure: compressBound always suffices.
    throw std::bad_alloc();
  }
  out.resize(size);
  return out;
}

size_t packed_bound(size_t raw) { return compressBound(static_cast<uLong>(raw)); }

std::string inflate_bytes(const uint8_t* data, size_t n, size_t expected, std::vector<uint8_t>& out) {
  if (n == 0) return "packed data is empty";
  if (n > packed_bound(expected)) {
    return std::to_string(n) + " packed bytes for " + std::to_string(expected) + " raw bytes (at most " +
           std::to_string(packed_bound(expected)) + ")";
  }
  out.resize(expected);
  z_stream zs{};
  if (inflateInit(&zs) != Z_OK) return "zlib: cannot initialise";
  zs.next_in = const_cast<Bytef*>(data);
  zs.avail_in = static_cast<uInt>(n);
  zs.next_out = out.data();
  zs.avail_out = static_cast<uInt>(expected);
  const int rc = inflate(&zs, Z_FINISH);
  const size_t produced = expected - zs.avail_out;
  const size_t consumed = n - zs.avail_in;
  inflateEnd(&zs);
  if (rc == Z_STREAM_END) {
    if (produced != expected) {
      return "unpacks to " + std::to_string(produced) + " bytes, " + std::to_string(expected) + " expected";
    }
    if (consumed != n) return std::to_string(n - consumed) + " bytes after the end of the packed data";
    return {};
  }
  if (rc == Z_BUF_ERROR && consumed == n) {
    return "truncated packed data (" + std::to_string(produced) + " of " + std::to_string(expected) +
           " bytes unpacked before the end)";
  }
  if (rc == Z_BUF_ERROR && zs.avail_out == 0) {
    return "unpacks to more than the " + std::to_string(expected) + " bytes expected";
  }
  return std::string("corrupt packed data (zlib: ") + (zs.msg != nullptr ? zs.msg : "truncated") + ")";
}

namespace {
constexpr size_t kPlanes = 6;  // the six low bytes of each point's 48-bit code delta
constexpr uint64_t kCodeLimit = uint64_t{1} << 48;

// Spreads the bits of v to every third bit (bit i to bit 3i).
uint64_t spread3(uint16_t v) {
  uint64_t x = v;
  x = (x | (x << 32)) & 0x001F00000000FFFFull;
  x = (x | (x << 16)) & 0x001F0000FF0000FFull;
  x = (x | (x << 8)) & 0x100F00F00F00F00Full;
  x = (x | (x << 4)) & 0x10C30C30C30C30C3ull;
  x = (x | (x << 2)) & 0x1249249249249249ull;
  return x;
}

// The inverse of spread3: gathers every third bit of x (from bit 0).
uint16_t gather3(uint64_t x) {
  x &= 0x1249249249249249ull;
  x = (x ^ (x >> 2)) & 0x10C30C30C30C30C3ull;
  x = (x ^ (x >> 4)) & 0x100F00F00F00F00Full;
  x = (x ^ (x >> 8)) & 0x001F0000FF0000FFull;
  x = (x ^ (x >> 16)) & 0x001F00000000FFFFull;
  x = (x ^ (x >> 32)) & 0xFFFFull;
  return static_cast<uint16_t>(x);
}

// Grid steps of a point, offset to unsigned (so that the code's order is spatial), interleaved
// into one 48-bit Morton code: points near each other in space have close codes.
uint64_t morton_code(const std::array<int16_t, 3>& v) {
  auto u = [](int16_t s) { return static_cast<uint16_t>(static_cast<uint16_t>(s) ^ 0x8000u); };
  return spread3(u(v[0])) | (spread3(u(v[1])) << 1) | (spread3(u(v[2])) << 2);
}

std::array<int16_t, 3> from_morton(uint64_t code) {
  auto s = [](uint16_t u) { return static_cast<int16_t>(static_cast<uint16_t>(u ^ 0x8000u)); };
  return {s(gather3(code)), s(gather3(code >> 1)), s(gather3(code >> 2))};
}
}  // namespace

PackedCloud pack_points(const std::vector<Eigen::Vector3f>& points, float resolution_m) {
  PackedCloud pc;
  pc.resolution_m = resolution_m;
  std::vector<uint64_t> codes;
  codes.reserve(points.size());
  const float inv = 1.0f / resolution_m;
  for (const Eigen::Vector3f& p : points) {
    std::array<int16_t, 3> v{};
    bool ok = true;
    for (int a = 0; a < 3; ++a) {
      const float s = std::round(p[a] * inv);
      if (!(s >= static_cast<float>(std::numeric_limits<int16_t>::min()) &&
            s <= static_cast<float>(std::numeric_limits<int16_t>::max()))) {
        ok = false;
        break;
      }
      v[static_cast<size_t>(a)] = static_cast<int16_t>(s);
    }
    if (ok) {
      codes.push_back(morton_code(v));
    } else {
      ++pc.dropped;
    }
  }
  std::sort(codes.begin(), codes.end());
  pc.count = static_cast<uint32_t>(codes.size());
  // Byte planes of the deltas between consecutive sorted codes: a cloud of surfaces gives mostly
  // small deltas, so the high planes are nearly all zero, which DEFLATE packs well (on simulated
  // KITTI-05 verification clouds 14 % smaller at 1 cm than per-axis deltas of points sorted by x).
  std::vector<uint8_t> raw(kPlanes * codes.size());
  uint64_t prev = 0;
  for (size_t i = 0; i < codes.size(); ++i) {
    const uint64_t d = codes[i] - prev;
    prev = codes[i];
    for (size_t k = 0; k < kPlanes; ++k) raw[k * codes.size() + i] = static_cast<uint8_t>(d >> (8 * k));
  }
  // No points pack to no bytes, which is what unpack_points takes for a count of 0.
  if (!codes.empty()) pc.bytes = deflate_bytes(raw.data(), raw.size());
  return pc;
}

std::string unpack_points(const uint8_t* data, size_t n, uint32_t count, float resolution_m,
                          std::vector<Eigen::Vector3f>& out) {
  out.clear();
  if (!(resolution_m > 0.0f) || !std::isfinite(resolution_m)) {
    return "resolution_m: must be a positive finite number";
  }
  if (count == 0) {
    return n == 0 ? std::string{} : std::to_string(n) + " packed bytes for 0 points";
  }
  std::vector<uint8_t> raw;
  const std::string err = inflate_bytes(data, n, kPlanes * size_t{count}, raw);
  if (!err.empty()) return err;
  out.reserve(count);
  uint64_t code = 0;
  for (size_t i = 0; i < count; ++i) {
    uint64_t d = 0;
    for (size_t k = 0; k < kPlanes; ++k) d |= uint64_t{raw[k * count + i]} << (8 * k);
    code += d;
    if (code >= kCodeLimit) {
      out.clear();
      return "point " + std::to_string(i) + "'s code runs past 48 bits (corrupt data)";
    }
    const std::array<int16_t, 3> v = from_morton(code);
    out.emplace_back(static_cast<float>(v[0]) * resolution_m, static_cast<float>(v[1]) * resolution_m,
                     static_cast<float>(v[2]) * resolution_m);
  }
  return {};
}

}  // namespace cdc::dds::compact
