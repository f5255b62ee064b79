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
constexpr size_t kPlanes = 6;  // per axis: low byte, high byte of the int16 delta
}

PackedCloud pack_points(const std::vector<Eigen::Vector3f>& points, float resolution_m) {
  PackedCloud pc;
  pc.resolution_m = resolution_m;
  std::vector<std::array<int16_t, 3>> q;
  q.reserve(points.size());
  const float inv = 1.0f / resolution_m;
  for (const Eigen::Vector3f& p : points) {
    std::array<int16_t, 3> v{};
    bool ok = true;
    for (int a = 0; a < 3; ++a) {
      const float s = std::round(p[a] * inv);
      if (!(std::abs(s) <= static_cast<float>(std::numeric_limits<int16_t>::max()))) {
        ok = false;
        break;
      }
      v[static_cast<size_t>(a)] = static_cast<int16_t>(s);
    }
    if (ok) {
      q.push_back(v);
    } else {
      ++pc.dropped;
    }
  }
  std::sort(q.begin(), q.end());
  pc.count = static_cast<uint32_t>(q.size());
  // Byte planes of the per-axis deltas (modulo 2^16): sorted points make the first axis' deltas
  // small and the planes of high bytes nearly constant, which DEFLATE packs well.
  std::vector<uint8_t> raw(kPlanes * q.size());
  std::array<uint16_t, 3> prev{0, 0, 0};
  for (size_t i = 0; i < q.size(); ++i) {
    for (size_t a = 0; a < 3; ++a) {
      const auto cur = static_cast<uint16_t>(q[i][a]);
      const auto d = static_cast<uint16_t>(cur - prev[a]);
      prev[a] = cur;
      raw[(2 * a) * q.size() + i] = static_cast<uint8_t>(d & 0xff);
      raw[(2 * a + 1) * q.size() + i] = static_cast<uint8_t>(d >> 8);
    }
  }
  pc.bytes = deflate_bytes(raw.data(), raw.size());
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
  std::array<uint16_t, 3> acc{0, 0, 0};
  for (size_t i = 0; i < count; ++i) {
    Eigen::Vector3f p;
    for (size_t a = 0; a < 3; ++a) {
      const auto d = static_cast<uint16_t>(raw[(2 * a) * count + i] | (raw[(2 * a + 1) * count + i] << 8));
      acc[a] = static_cast<uint16_t>(acc[a] + d);
      p[static_cast<Eigen::Index>(a)] = static_cast<float>(static_cast<int16_t>(acc[a])) * resolution_m;
    }
    out.push_back(p);
  }
  return {};
}

}  // namespace cdc::dds::compact
