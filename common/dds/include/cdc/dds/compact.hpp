// Compact wire encodings for the samples that cross the robots' radio links: a lossless DEFLATE
// packing of byte blocks (descriptor cells) and a quantised, delta-coded, deflated packing of
// point clouds (cloud replies for loop verification). Both decoders check everything they read
// and report what is wrong instead of throwing: the input comes off the network.
#pragma once

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cdc::dds::compact {

// DEFLATE (zlib format, best compression) of `n` bytes.
std::vector<uint8_t> deflate_bytes(const uint8_t* data, size_t n);

// Inflates `n` packed bytes into `out`, which must come out exactly `expected` bytes long.
// Returns an empty string on success, else why the data is unusable.
std::string inflate_bytes(const uint8_t* data, size_t n, size_t expected, std::vector<uint8_t>& out);

// Largest packed size accepted for `raw` bytes (zlib's own bound for incompressible input).
size_t packed_bound(size_t raw);

// A point cloud packed for the wire. Points are rounded to a grid of `resolution_m` (int16 per
// axis, so coordinates must lie within +-32767 steps), interleaved into 48-bit Morton codes, sorted,
// stored as deltas between consecutive codes in byte planes and deflated. The point order is not
// kept (points come back in Morton order). Rounding moves a point by at most half a
// step per axis. A cloud with no points (or none in range) packs to no bytes.
struct PackedCloud {
  float resolution_m = 0.01f;
  uint32_t count = 0;          // points stored
  uint32_t dropped = 0;        // points outside the int16 range (not stored)
  std::vector<uint8_t> bytes;  // the packed data
};
PackedCloud pack_points(const std::vector<Eigen::Vector3f>& points, float resolution_m);

// Decodes `count` points packed with `resolution_m` into `out` (replacing its contents). Returns an
// empty string on success, else why the data is unusable.
std::string unpack_points(const uint8_t* data, size_t n, uint32_t count, float resolution_m,
                          std::vector<Eigen::Vector3f>& out);

}  // namespace cdc::dds::compact
