#include "decompress.hpp"

#include "cdc/io/error.hpp"

#include <lz4frame.h>
#include <zlib.h>
#include <zstd.h>

#include <algorithm>
#include <limits>
#include <memory>

namespace cdc::io::detail {
namespace {

[[noreturn]] void fail(const std::string& where, const std::string& what) { throw FormatError(where + ": " + what); }

void check_size(uint64_t size, uint64_t max_size, const std::string& where) {
  if (size > max_size || size > std::numeric_limits<size_t>::max()) {
    fail(where,
         "claims " + std::to_string(size) + " decompressed bytes, more than the limit of " + std::to_string(max_size));
  }
}

// Next output capacity: doubling, bounded by cap.
size_t grow(size_t current, uint64_t cap) {
  const uint64_t next = std::max<uint64_t>(uint64_t{64} << 10, uint64_t{current} * 2);
  return static_cast<size_t>(std::min(next, cap));
}

size_t initial_capacity(size_t input_size, uint64_t cap) {
  return static_cast<size_t>(std::min<uint64_t>(uint64_t{input_size} * 4 + 4096, cap));
}

}  // namespace

std::vector<uint8_t> zstd_decompress(std::span<const uint8_t> in, std::optional<uint64_t> expected_size,
                                     const std::string& where, uint64_t max_size) {
  if (expected_size) check_size(*expected_size, max_size, where);
  if (in.empty()) fail(where, "zstd data are empty");
  std::unique_ptr<ZSTD_DStream, decltype(&ZSTD_freeDStream)> ds(ZSTD_createDStream(), ZSTD_freeDStream);
  if (!ds) fail(where, "cannot create a zstd decoder");
  // Capacity grows with the output actually produced, up to the expected size or the limit, so a
  // damaged size field costs no memory.
  const uint64_t cap = expected_size ? *expected_size : max_size;
  std::vector<uint8_t> out(initial_capacity(in.size(), cap));
  ZSTD_inBuffer src{in.data(), in.size(), 0};
  ZSTD_outBuffer dst{out.data(), out.size(), 0};
  size_t hint = 1;  // nonzero while a frame is unfinished
  while (src.pos < src.size || hint != 0) {
    if (dst.pos == dst.size && out.size() < cap) {
      out.resize(grow(out.size(), cap));
      dst.dst = out.data();
      dst.size = out.size();
    }
    const size_t before_in = src.pos, before_out = dst.pos;
    hint = ZSTD_decompressStream(ds.get(), &dst, &src);
    if (ZSTD_isError(hint)) fail(where, std::string("zstd: ") + ZSTD_getErrorName(hint));
    if (hint != 0 && src.pos == before_in && dst.pos == before_out) {
      if (dst.pos == dst.size) {
        fail(where, "zstd data decode to more than " + std::to_string(dst.size) + " bytes");
      }
      fail(where, "zstd data end inside a frame (truncated)");
    }
  }
  if (expected_size && dst.pos != *expected_size) {
    fail(where,
         "zstd data decode to " + std::to_string(dst.pos) + " bytes, expected " + std::to_string(*expected_size));
  }
  out.resize(dst.pos);
  return out;
}

std::vector<uint8_t> lz4_decompress(std::span<const uint8_t> in, std::optional<uint64_t> expected_size,
                                    const std::string& where, uint64_t max_size) {
  if (expected_size) check_size(*expected_size, max_size, where);
  if (in.empty()) fail(where, "LZ4 data are empty");
  LZ4F_dctx* raw_ctx = nullptr;
  if (LZ4F_isError(LZ4F_createDecompressionContext(&raw_ctx, LZ4F_VERSION))) {
    fail(where, "cannot create an LZ4 decoder");
  }
  std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> ctx(raw_ctx, LZ4F_freeDecompressionContext);
  const uint64_t cap = expected_size ? *expected_size : max_size;
  std::vector<uint8_t> out(initial_capacity(in.size(), cap));
  size_t src_pos = 0, dst_pos = 0;
  size_t hint = 1;  // nonzero while a frame is unfinished
  while (src_pos < in.size() || hint != 0) {
    if (dst_pos == out.size() && out.size() < cap) {
      out.resize(grow(out.size(), cap));
    }
    size_t src_size = in.size() - src_pos, dst_size = out.size() - dst_pos;
    hint = LZ4F_decompress(ctx.get(), out.data() + dst_pos, &dst_size, in.data() + src_pos, &src_size, nullptr);
    if (LZ4F_isError(hint)) fail(where, std::string("LZ4: ") + LZ4F_getErrorName(hint));
    src_pos += src_size;
    dst_pos += dst_size;
    if (hint != 0 && src_size == 0 && dst_size == 0) {
      if (dst_pos == out.size()) {
        fail(where, "LZ4 data decode to more than " + std::to_string(out.size()) + " bytes");
      }
      fail(where, "LZ4 data end inside a frame (truncated)");
    }
  }
  if (expected_size && dst_pos != *expected_size) {
    fail(where, "LZ4 data decode to " + std::to_string(dst_pos) + " bytes, expected " + std::to_string(*expected_size));
  }
  out.resize(dst_pos);
  return out;
}

uint32_t crc32(std::span<const uint8_t> bytes) {
  uLong crc = ::crc32(0L, Z_NULL, 0);
  size_t pos = 0;
  while (pos < bytes.size()) {
    const size_t n = std::min<size_t>(bytes.size() - pos, std::numeric_limits<uInt>::max());
    crc = ::crc32(crc, bytes.data() + pos, static_cast<uInt>(n));
    pos += n;
  }
  return static_cast<uint32_t>(crc);
}

}  // namespace cdc::io::detail
