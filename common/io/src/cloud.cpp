#include "cdc/io/cloud.hpp"

#include "cdc/io/error.hpp"

#include <cstring>
#include <fstream>
#include <string>

namespace cdc::io {
namespace fs = std::filesystem;
namespace {

std::vector<char> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary | std::ios::ate);
  if (!in) throw FormatError(p.string() + ": cannot open");
  const std::streamoff size = in.tellg();
  if (size < 0) throw FormatError(p.string() + ": cannot tell its size");
  std::vector<char> bytes(static_cast<size_t>(size));
  in.seekg(0);
  if (!in.read(bytes.data(), size)) throw FormatError(p.string() + ": read failed");
  return bytes;
}

void write_bytes(const fs::path& p, const void* data, size_t size) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error(p.string() + ": cannot write");
  out.write(static_cast<const char*>(data), static_cast<std::streamsize>(size));
  if (!out) throw std::runtime_error(p.string() + ": write failed");
}

}  // namespace

std::vector<CloudPoint> read_kitti_bin(const fs::path& path) {
  const std::vector<char> bytes = read_bytes(path);
  if (bytes.size() % 16 != 0) {
    throw FormatError(path.string() + ": size " + std::to_string(bytes.size()) + " is not a multiple of 16 bytes");
  }
  std::vector<CloudPoint> pts(bytes.size() / 16);
  for (size_t i = 0; i < pts.size(); ++i) {
    float v[4];
    std::memcpy(v, bytes.data() + 16 * i, sizeof v);
    pts[i].x = v[0];
    pts[i].y = v[1];
    pts[i].z = v[2];
    pts[i].intensity = v[3];
  }
  return pts;
}

void write_kitti_bin(const fs::path& path, const std::vector<CloudPoint>& points) {
  std::vector<float> v(points.size() * 4);
  for (size_t i = 0; i < points.size(); ++i) {
    v[4 * i] = points[i].x;
    v[4 * i + 1] = points[i].y;
    v[4 * i + 2] = points[i].z;
    v[4 * i + 3] = points[i].intensity;
  }
  write_bytes(path, v.data(), v.size() * sizeof(float));
}

void read_point_meta(const fs::path& path, std::vector<CloudPoint>& points) {
  const std::vector<char> bytes = read_bytes(path);
  if (bytes.size() != points.size() * 8) {
    throw FormatError(path.string() + ": " + std::to_string(bytes.size() / 8) + " entries for " +
                      std::to_string(points.size()) + " points");
  }
  for (size_t i = 0; i < points.size(); ++i) {
    std::memcpy(&points[i].time_offset, bytes.data() + 8 * i, 4);
    std::memcpy(&points[i].ring, bytes.data() + 8 * i + 4, 2);
  }
}

void write_point_meta(const fs::path& path, const std::vector<CloudPoint>& points) {
  std::vector<char> bytes(points.size() * 8, 0);
  for (size_t i = 0; i < points.size(); ++i) {
    std::memcpy(bytes.data() + 8 * i, &points[i].time_offset, 4);
    std::memcpy(bytes.data() + 8 * i + 4, &points[i].ring, 2);
  }
  write_bytes(path, bytes.data(), bytes.size());
}

}  // namespace cdc::io
