// Whole-buffer decompression of the frame formats bags use (Zstandard, LZ4 frame), with every size
// checked: a stream that is damaged, truncated, or decodes to another size than expected throws
// FormatError prefixed with the caller's description of the place.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace cdc::io::detail {

// Upper bound on one decompressed buffer: protects against sizes claimed by damaged files.
constexpr uint64_t kMaxDecompressedBytes = uint64_t{4} << 30;  // 4 GiB

// Decodes one or more concatenated zstd frames. With expected_size the output must have exactly that
// size; without it the output may grow up to max_size.
std::vector<uint8_t> zstd_decompress(std::span<const uint8_t> in, std::optional<uint64_t> expected_size,
                                     const std::string& where, uint64_t max_size = kMaxDecompressedBytes);

// Decodes one or more concatenated LZ4 frames (the LZ4 frame format, not raw blocks).
std::vector<uint8_t> lz4_decompress(std::span<const uint8_t> in, std::optional<uint64_t> expected_size,
                                    const std::string& where, uint64_t max_size = kMaxDecompressedBytes);

// CRC-32 (IEEE 802.3, as zlib computes it).
uint32_t crc32(std::span<const uint8_t> bytes);

}  // namespace cdc::io::detail
