#include "cdc/odometry/normals.hpp"

#include "kdtree.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace cdc::odometry {

std::vector<Eigen::Vector3d> range_image_normals(const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<uint16_t>& rings, int columns,
                                                 double max_neighbour_m) {
  const size_t n = points.size();
  std::vector<Eigen::Vector3d> normals(n, Eigen::Vector3d::Zero());
  if (n == 0 || rings.size() != n) return normals;
  int nrings = 0;
  for (uint16_t r : rings) nrings = std::max(nrings, static_cast<int>(r) + 1);
  std::vector<int> image(static_cast<size_t>(nrings) * static_cast<size_t>(columns), -1);
  std::vector<int> col(n);
  std::vector<char> usable(n, 0);
  for (size_t i = 0; i < n; ++i) {
    if (!points[i].allFinite()) continue;  // never index the image with a non-finite angle
    usable[i] = 1;
    double az = std::atan2(points[i].y(), points[i].x());
    if (az < 0) az += 2 * M_PI;
    col[i] = std::min(columns - 1, static_cast<int>(az / (2 * M_PI) * columns));
    image[static_cast<size_t>(rings[i]) * static_cast<size_t>(columns) + static_cast<size_t>(col[i])] =
        static_cast<int>(i);
  }
  const double lim2 = max_neighbour_m * max_neighbour_m;
  auto at = [&](int r, int c) -> int {
    if (r < 0 || r >= nrings) return -1;
    c = (c % columns + columns) % columns;
    return image[static_cast<size_t>(r) * static_cast<size_t>(columns) + static_cast<size_t>(c)];
  };
  // The nearest filled cell within a few columns in the given direction.
  auto find = [&](int r, int c, int step) -> int {
    for (int k = 1; k <= 4; ++k) {
      const int j = at(r, c + step * k);
      if (j >= 0) return j;
    }
    return -1;
  };
  for (size_t i = 0; i < n; ++i) {
    if (!usable[i]) continue;
    const int r = rings[i], c = col[i];
    const Eigen::Vector3d& p = points[i];
    const int a = find(r, c, 1), b = find(r, c, -1);
    int u = -1, d = -1;
    for (int k = 0; k <= 2 && u < 0; ++k) u = at(r + 1, c + k) >= 0 ? at(r + 1, c + k) : at(r + 1, c - k);
    for (int k = 0; k <= 2 && d < 0; ++k) d = at(r - 1, c + k) >= 0 ? at(r - 1, c + k) : at(r - 1, c - k);
    const int along = a >= 0 ? a : b, across = u >= 0 ? u : d;
    if (along < 0 || across < 0) continue;
    const Eigen::Vector3d t1 = points[static_cast<size_t>(along)] - p, t2 = points[static_cast<size_t>(across)] - p;
    if (t1.squaredNorm() > lim2 || t2.squaredNorm() > lim2) continue;
    Eigen::Vector3d nrm = t1.cross(t2);
    const double len = nrm.norm();
    if (len < 1e-9 || len < 0.2 * t1.norm() * t2.norm()) continue;  // nearly collinear
    nrm /= len;
    // Coplanarity: the other neighbours must lie near the plane.
    bool ok = true;
    for (int j : {a, b, u, d}) {
      if (j < 0) continue;
      const Eigen::Vector3d v = points[static_cast<size_t>(j)] - p;
      if (v.squaredNorm() <= lim2 && std::abs(nrm.dot(v)) > 0.1 + 0.05 * v.norm()) ok = false;
    }
    if (ok) normals[i] = nrm;
  }
  return normals;
}

std::vector<Eigen::Vector3d> knn_normals(const std::vector<Eigen::Vector3d>& queries,
                                         const std::vector<Eigen::Vector3d>& cloud, int k, double max_neighbour_m) {
  std::vector<Eigen::Vector3d> normals(queries.size(), Eigen::Vector3d::Zero());
  if (cloud.size() < static_cast<size_t>(k) || k < 3) return normals;
  detail::CloudAdaptor adaptor{&cloud};
  const detail::KdTree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));  // built by its constructor
  std::vector<size_t> idx(static_cast<size_t>(k));
  std::vector<double> d2(static_cast<size_t>(k));
  const double lim2 = max_neighbour_m * max_neighbour_m;
  for (size_t i = 0; i < queries.size(); ++i) {
    const size_t found = tree.knnSearch(queries[i].data(), static_cast<size_t>(k), idx.data(), d2.data());
    if (found < static_cast<size_t>(k) || d2[found - 1] > lim2) continue;
    const Eigen::Matrix3d cov = detail::neighbour_scatter(cloud, idx.data(), found);
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
    const Eigen::Vector3d ev = es.eigenvalues();  // ascending
    // Planar: the normal's spread small against the middle one (a line has two small ones).
    if (ev(0) > 0.1 * ev(1) || ev(1) < 0.05 * ev(2)) continue;
    normals[i] = es.eigenvectors().col(0);
  }
  return normals;
}

}  // namespace cdc::odometry
