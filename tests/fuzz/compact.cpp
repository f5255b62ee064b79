// The packed formats that cross the radio (common/dds/compact): point clouds of loop-verification
// replies and the DEFLATE-packed cells of Scan Context descriptors, decoded as a receiving robot
// does after its message checks. Selector bit 0 picks the format. A decoded cloud packed again must
// decode to the same points; decoded cells packed again must inflate to the same bytes.
#include "cdc/dds/compact.hpp"
#include "cdc/lidar/scan_context.hpp"
#include "fuzz_support.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>

namespace {

namespace compact = cdc::dds::compact;

template <class T>
T take(std::span<const uint8_t>& bytes) {
  T v{};
  const size_t n = std::min(sizeof(T), bytes.size());
  if (n > 0) std::memcpy(&v, bytes.data(), n);
  bytes = bytes.subspan(n);
  return v;
}

bool less(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
  return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
}

// Header: uint16 point count, uint8 resolution in mm - 1; then the packed bytes.
void cloud(std::span<const uint8_t> bytes) {
  const uint32_t count = take<uint16_t>(bytes);
  const float resolution = 0.001f * static_cast<float>(take<uint8_t>(bytes) + 1);
  std::vector<Eigen::Vector3f> points;
  if (bytes.size() > compact::packed_bound(6 * size_t{count})) return;  // refused by the message checks
  if (!compact::unpack_points(bytes.data(), bytes.size(), count, resolution, points).empty()) return;
  if (points.size() != count) std::abort();
  const compact::PackedCloud packed = compact::pack_points(points, resolution);
  std::vector<Eigen::Vector3f> again;
  if (packed.dropped != 0 ||
      !compact::unpack_points(packed.bytes.data(), packed.bytes.size(), packed.count, resolution, again).empty()) {
    std::abort();
  }
  std::sort(points.begin(), points.end(), less);
  std::sort(again.begin(), again.end(), less);
  if (points != again) std::abort();
}

// Header: uint16 rings, uint16 sectors, float quantisation scale; then the packed cells.
void descriptor(std::span<const uint8_t> bytes) {
  cdc::lidar::QuantizedScanContext q;
  q.rings = take<uint16_t>(bytes);
  q.sectors = take<uint16_t>(bytes);
  q.scale = take<float>(bytes);
  const size_t cells = size_t(q.rings) * size_t(q.sectors);
  // What the message checks refuse before decoding (validate.cpp).
  if (cells == 0 || cells > 65536 || !(q.scale > 0.0f) || !std::isfinite(q.scale)) return;
  if (bytes.size() > compact::packed_bound(cells)) return;
  if (!compact::inflate_bytes(bytes.data(), bytes.size(), cells, q.cells).empty()) return;
  (void)cdc::lidar::dequantize(q);
  const std::vector<uint8_t> packed = compact::deflate_bytes(q.cells.data(), q.cells.size());
  std::vector<uint8_t> again;
  if (!compact::inflate_bytes(packed.data(), packed.size(), cells, again).empty() || again != q.cells) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const cdc::fuzz::Input in(data, size);
  if ((in.selector & 1) == 0) {
    cloud(in.rest);
  } else {
    descriptor(in.rest);
  }
  return 0;
}
