#include "cdc/odometry/pair_registration.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/voxel_map.hpp"
#include "kdtree.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace cdc::odometry {

namespace {

// Each point's covariance from its k nearest neighbours, with the eigenvalues replaced by
// (1e-3, 1, 1): a plane through the neighbourhood, certain along its normal (GICP's plane-to-plane).
std::vector<Eigen::Matrix3d> plane_covariances(const std::vector<Eigen::Vector3d>& cloud, const detail::KdTree& tree,
                                               int k) {
  std::vector<Eigen::Matrix3d> out(cloud.size(), Eigen::Matrix3d::Identity());
  std::vector<size_t> idx(static_cast<size_t>(k));
  std::vector<double> d2(static_cast<size_t>(k));
  for (size_t i = 0; i < cloud.size(); ++i) {
    const size_t found = tree.knnSearch(cloud[i].data(), static_cast<size_t>(k), idx.data(), d2.data());
    if (found < 5) continue;
    const Eigen::Matrix3d cov = detail::neighbour_scatter(cloud, idx.data(), found);
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    out[i] = es.eigenvectors() * Eigen::Vector3d(1e-3, 1, 1).asDiagonal() * es.eigenvectors().transpose();
  }
  return out;
}

// For each source point moved by T, the distance to its nearest point in the tree's cloud (not empty).
std::vector<double> distances_to(const detail::KdTree& tree, const std::vector<Eigen::Vector3d>& source,
                                 const Eigen::Isometry3d& T) {
  std::vector<double> out(source.size(), std::numeric_limits<double>::infinity());
  for (size_t i = 0; i < source.size(); ++i) {
    const Eigen::Vector3d q = T * source[i];
    size_t j = 0;
    double d2 = 0;
    if (tree.knnSearch(q.data(), 1, &j, &d2) == 1) out[i] = std::sqrt(d2);
  }
  return out;
}

RegistrationOutput gicp(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                        const Eigen::Isometry3d& guess, const PairRegistrationParams& params) {
  const bool reduce = params.gicp_voxel_m > 0;
  const GicpCloud src(reduce ? voxel_centroids(source, params.gicp_voxel_m) : source, params.gicp_neighbours);
  const GicpCloud tgt(reduce ? voxel_centroids(target, params.gicp_voxel_m) : target, params.gicp_neighbours);
  return register_gicp(src, tgt, guess, params);
}

}  // namespace

struct GicpCloud::Impl {
  std::vector<Eigen::Vector3d> points;
  detail::CloudAdaptor adaptor{&points};
  detail::KdTree tree{3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)};
  std::vector<Eigen::Matrix3d> covariances;
  explicit Impl(std::vector<Eigen::Vector3d> p) : points(std::move(p)) {}
};

GicpCloud::GicpCloud(std::vector<Eigen::Vector3d> points, int neighbours)
    : impl_(std::make_unique<Impl>(std::move(points))) {
  // The tree was built when it was made (nanoflann builds in its constructor).
  impl_->covariances = plane_covariances(impl_->points, impl_->tree, neighbours);
}

GicpCloud::~GicpCloud() = default;

const std::vector<Eigen::Vector3d>& GicpCloud::points() const { return impl_->points; }

std::vector<double> GicpCloud::nearest_distances(const std::vector<Eigen::Vector3d>& source,
                                                 const Eigen::Isometry3d& T) const {
  if (impl_->points.empty()) return std::vector<double>(source.size(), std::numeric_limits<double>::infinity());
  return distances_to(impl_->tree, source, T);
}

RegistrationOutput register_gicp(const GicpCloud& source, const GicpCloud& target, const Eigen::Isometry3d& guess,
                                 const PairRegistrationParams& params) {
  const std::vector<Eigen::Vector3d>& src = source.points();
  const std::vector<Eigen::Vector3d>& tgt = target.points();
  const std::vector<Eigen::Matrix3d>& cs = source.impl().covariances;
  const std::vector<Eigen::Matrix3d>& ct = target.impl().covariances;
  const detail::KdTree& ttree = target.impl().tree;
  const double max2 = params.gicp_max_correspondence_m * params.gicp_max_correspondence_m;
  RegistrationOutput out;
  out.T_map_sensor = guess;
  for (int it = 0; it < params.gicp_max_iterations; ++it) {
    const Eigen::Matrix3d R = out.T_map_sensor.rotation();
    Matrix6d H = Matrix6d::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    int n = 0;
    double sum2 = 0;
    for (size_t i = 0; i < src.size(); ++i) {
      const Eigen::Vector3d q = out.T_map_sensor * src[i];
      size_t j = 0;
      double d2 = 0;
      if (ttree.knnSearch(q.data(), 1, &j, &d2) < 1 || d2 > max2) continue;
      const Eigen::Matrix3d M = (ct[j] + R * cs[i] * R.transpose()).inverse();
      const Eigen::Vector3d e = tgt[j] - q;
      // d(T Exp(dx) s)/d(dx) = R [I, -hat(s)] (right perturbation, (t, r) order); e = target - that.
      Eigen::Matrix<double, 3, 6> J;
      J.leftCols<3>() = -R;
      J.rightCols<3>() = R * geometry::hat(src[i]);
      H.noalias() += J.transpose() * M * J;
      b.noalias() += J.transpose() * M * e;
      ++n;
      sum2 += d2;
    }
    out.correspondences = n;
    out.iterations = it + 1;
    out.hessian = H;
    out.rmse = n > 0 ? std::sqrt(sum2 / n) : 0;
    if (n < 20) return out;
    const Eigen::Matrix<double, 6, 1> dx = H.ldlt().solve(-b);
    if (!dx.allFinite()) return out;
    out.T_map_sensor = out.T_map_sensor * geometry::se3_exp(dx);
    if (dx.head<3>().norm() < 1e-5 && dx.tail<3>().norm() < 1e-6) {
      out.converged = true;
      break;
    }
  }
  return out;
}

RegistrationOutput register_pair(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                                 const Eigen::Isometry3d& guess, const PairRegistrationParams& params) {
  if (params.method == PairMethod::kGicp) return gicp(source, target, guess, params);
  VoxelMap map(VoxelMapParams{params.map_voxel_m, 1000.0, 20});  // no pruning: one target sweep
  map.add(voxel_filter(target, params.target_voxel_m));
  const std::vector<Eigen::Vector3d> src = voxel_filter(source, params.source_voxel_m);
  const std::vector<Eigen::Vector3d> normals =
      knn_normals(src, source, params.normal_neighbours, params.normal_radius_m);
  RegistrationOutput out;
  out.T_map_sensor = guess;
  for (const double gate : params.gates_m) {
    RegistrationParams p;
    p.max_correspondence_m = gate;
    p.kernel_m = gate / 3;
    out = register_to_map(src, normals, map, out.T_map_sensor, p);
  }
  return out;
}

std::vector<double> nearest_distances(const std::vector<Eigen::Vector3d>& source,
                                      const std::vector<Eigen::Vector3d>& target,
                                      const Eigen::Isometry3d& T_target_source) {
  if (target.empty()) return std::vector<double>(source.size(), std::numeric_limits<double>::infinity());
  const detail::CloudAdaptor adaptor{&target};
  const detail::KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));
  return distances_to(tree, source, T_target_source);
}

AlignmentScore score_alignment(const std::vector<Eigen::Vector3d>& source, const std::vector<Eigen::Vector3d>& target,
                               const Eigen::Isometry3d& T_target_source, double voxel_m, double max_distance_m) {
  const std::vector<Eigen::Vector3d> src = voxel_filter(source, voxel_m), tgt = voxel_filter(target, voxel_m);
  const std::vector<Eigen::Vector3d> normals = knn_normals(tgt, tgt, 10, 1.0);
  detail::CloudAdaptor adaptor{&tgt};
  const detail::KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));  // built by its constructor
  AlignmentScore out;
  double sum2 = 0;
  for (const Eigen::Vector3d& p : src) {
    const Eigen::Vector3d q = T_target_source * p;
    size_t j = 0;
    double d2 = 0;
    if (tree.knnSearch(q.data(), 1, &j, &d2) < 1 || d2 > max_distance_m * max_distance_m) continue;
    if (normals[j].squaredNorm() < 0.5) continue;  // not on a plane
    const double r = normals[j].dot(q - tgt[j]);
    sum2 += r * r;
    ++out.matched;
    if (std::abs(r) <= 0.01) ++out.within_1cm;
    if (std::abs(r) <= 0.02) ++out.within_2cm;
  }
  out.source_points = src.size();
  out.rms_point_to_plane_m = out.matched > 0 ? std::sqrt(sum2 / static_cast<double>(out.matched)) : 0.0;
  return out;
}

namespace {

std::string read_all(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error(path + ": cannot be read");
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

[[noreturn]] void bad(const std::string& path, const std::string& what) {
  throw std::runtime_error(path + ": " + what);
}

// Float32 x, y, z at the given byte offsets of records of `stride` bytes from `begin`.
std::vector<Eigen::Vector3d> records(const std::string& path, const std::string& bytes, size_t begin, size_t stride,
                                     size_t count, const size_t offset[3]) {
  if (bytes.size() < begin || (bytes.size() - begin) / stride < count) {
    bad(path, "truncated: " + std::to_string(count) + " points of " + std::to_string(stride) + " B announced, " +
                  std::to_string(bytes.size() - std::min(bytes.size(), begin)) + " B of data");
  }
  std::vector<Eigen::Vector3d> out;
  out.reserve(count);
  for (size_t i = 0; i < count; ++i) {
    float v[3];
    for (int k = 0; k < 3; ++k) std::memcpy(&v[k], bytes.data() + begin + i * stride + offset[k], 4);
    if (std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2])) out.emplace_back(v[0], v[1], v[2]);
  }
  return out;
}

std::vector<Eigen::Vector3d> read_pcd(const std::string& path, const std::string& bytes) {
  std::istringstream header(bytes);
  std::string line;
  std::vector<std::string> fields;
  std::vector<size_t> sizes, counts;
  std::vector<char> types;
  size_t points = 0, consumed = 0;
  std::string data;
  while (std::getline(header, line)) {
    consumed += line.size() + 1;
    std::istringstream l(line);
    std::string key;
    l >> key;
    if (key == "FIELDS") {
      for (std::string f; l >> f;) fields.push_back(f);
    } else if (key == "SIZE") {
      for (size_t v; l >> v;) sizes.push_back(v);
    } else if (key == "TYPE") {
      for (char v; l >> v;) types.push_back(v);
    } else if (key == "COUNT") {
      for (size_t v; l >> v;) counts.push_back(v);
    } else if (key == "POINTS") {
      l >> points;
    } else if (key == "DATA") {
      l >> data;
      break;
    }
  }
  if (data != "binary") bad(path, "PCD DATA '" + data + "' is not supported (binary only)");
  if (fields.empty() || sizes.size() != fields.size() || types.size() != fields.size()) {
    bad(path, "PCD header without matching FIELDS, SIZE and TYPE");
  }
  if (counts.empty()) counts.assign(fields.size(), 1);
  if (counts.size() != fields.size()) bad(path, "PCD COUNT does not match FIELDS");
  size_t offset[3] = {0, 0, 0}, stride = 0;
  int found = 0;
  for (size_t i = 0; i < fields.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      if (fields[i] == std::string(1, static_cast<char>('x' + k))) {
        if (types[i] != 'F' || sizes[i] != 4) bad(path, "PCD field " + fields[i] + " is not float32");
        offset[k] = stride;
        ++found;
      }
    }
    stride += sizes[i] * counts[i];
  }
  if (found != 3) bad(path, "PCD has no x, y and z fields");
  return records(path, bytes, consumed, stride, points, offset);
}

std::vector<Eigen::Vector3d> read_ply(const std::string& path, const std::string& bytes) {
  const size_t end = bytes.find("end_header\n");
  if (bytes.rfind("ply", 0) != 0 || end == std::string::npos) bad(path, "not a PLY file (no 'ply' ... 'end_header')");
  std::istringstream header(bytes.substr(0, end));
  std::string line;
  size_t vertices = 0, stride = 0, offset[3] = {0, 0, 0};
  int found = 0;
  bool in_vertex = false, binary_le = false;
  while (std::getline(header, line)) {
    std::istringstream l(line);
    std::string key;
    l >> key;
    if (key == "format") {
      std::string f;
      l >> f;
      binary_le = f == "binary_little_endian";
      if (!binary_le) bad(path, "PLY format '" + f + "' is not supported (binary_little_endian only)");
    } else if (key == "element") {
      std::string name;
      l >> name;
      in_vertex = name == "vertex";
      if (in_vertex)
        l >> vertices;
      else if (vertices == 0)
        bad(path, "PLY element '" + name + "' before the vertices is not supported");
    } else if (key == "property" && in_vertex) {
      std::string type, name;
      l >> type >> name;
      size_t size = 0;
      if (type == "float" || type == "float32" || type == "int" || type == "uint" || type == "int32" ||
          type == "uint32")
        size = 4;
      else if (type == "double" || type == "float64")
        size = 8;
      else if (type == "uchar" || type == "char" || type == "uint8" || type == "int8")
        size = 1;
      else if (type == "short" || type == "ushort" || type == "int16" || type == "uint16")
        size = 2;
      else
        bad(path, "PLY vertex property type '" + type + "' is not supported");
      for (int k = 0; k < 3; ++k) {
        if (name == std::string(1, static_cast<char>('x' + k))) {
          if (size != 4 || type.rfind("float", 0) != 0) bad(path, "PLY property " + name + " is not float32");
          offset[k] = stride;
          ++found;
        }
      }
      stride += size;
    }
  }
  if (!binary_le) bad(path, "PLY without a format line");
  if (found != 3) bad(path, "PLY vertices have no x, y and z");
  return records(path, bytes, end + std::strlen("end_header\n"), stride, vertices, offset);
}

}  // namespace

std::vector<Eigen::Vector3d> read_cloud_file(const std::string& path) {
  const size_t dot = path.rfind('.');
  const std::string ext = dot == std::string::npos ? "" : path.substr(dot);
  if (ext != ".bin" && ext != ".pcd" && ext != ".ply") {
    bad(path, "unknown point cloud format '" + ext + "' (KITTI .bin, binary .pcd or binary .ply)");
  }
  const std::string bytes = read_all(path);
  if (ext == ".pcd") return read_pcd(path, bytes);
  if (ext == ".ply") return read_ply(path, bytes);
  if (bytes.size() % 16 != 0)
    bad(path, "KITTI .bin size " + std::to_string(bytes.size()) + " B is not a multiple of 16");
  const size_t offset[3] = {0, 4, 8};
  return records(path, bytes, 0, 16, bytes.size() / 16, offset);
}

Eigen::Isometry3d read_matrix_file(const std::string& path) {
  std::istringstream in(read_all(path));
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) {
    if (!(in >> m(i / 4, i % 4)))
      bad(path, "expected 16 numbers (a 4x4 matrix, row by row), found " + std::to_string(i));
  }
  if (std::string rest; in >> rest) bad(path, "more than 16 numbers");
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    bad(path, "not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

}  // namespace cdc::odometry
