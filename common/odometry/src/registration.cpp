#include "cdc/odometry/registration.hpp"

#include "cdc/geometry/se3.hpp"
#include "kdtree.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace cdc::odometry {

RegistrationOutput register_to_map(const std::vector<Eigen::Vector3d>& pts, const std::vector<Eigen::Vector3d>& normals,
                                   const VoxelMap& map, const Eigen::Isometry3d& guess, const RegistrationParams& p) {
  RegistrationOutput out;
  out.T_map_sensor = guess;
  const double gate2 = p.max_correspondence_m * p.max_correspondence_m;
  const double k2 = p.kernel_m * p.kernel_m;
  for (int it = 0; it < p.max_iterations; ++it) {
    Matrix6d H = Matrix6d::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    const Eigen::Matrix3d R = out.T_map_sensor.rotation();
    const Eigen::Vector3d t = out.T_map_sensor.translation();
    int n = 0;
    double sum2 = 0;
    Eigen::Vector3d q;
    double d2 = 0;
    for (size_t i = 0; i < pts.size(); ++i) {
      const Eigen::Vector3d& ps = pts[i];
      if (normals[i].squaredNorm() < 0.5) continue;
      const Eigen::Vector3d pw = R * ps + t;
      if (!map.nearest(pw, q, d2, gate2)) continue;
      const Eigen::Vector3d nw = R * normals[i];
      const double e = nw.dot(pw - q);
      const double s = k2 + e * e;
      const double w = k2 * k2 / (s * s);  // Geman-McClure
      Eigen::Matrix<double, 1, 6> J;
      J.leftCols<3>() = nw.transpose() * R;
      J.rightCols<3>() = -nw.transpose() * R * geometry::hat(ps);
      H.noalias() += w * J.transpose() * J;
      b.noalias() += w * J.transpose() * e;
      ++n;
      sum2 += e * e;
    }
    out.correspondences = n;
    out.iterations = it + 1;
    out.hessian = H;
    out.rmse = n > 0 ? std::sqrt(sum2 / n) : 0;
    if (n < 20) {
      return out;  // not converged
    }
    const Eigen::Matrix<double, 6, 1> dx = H.ldlt().solve(-b);
    if (!dx.allFinite()) {
      return out;
    }
    out.T_map_sensor = out.T_map_sensor * geometry::se3_exp(dx);
    if (dx.head<3>().norm() < p.convergence && dx.tail<3>().norm() < p.convergence) {
      out.converged = true;
      break;
    }
  }
  if (!out.converged) out.converged = out.correspondences >= 20;
  return out;
}

FitQuality evaluate_fit(const std::vector<Eigen::Vector3d>& pts, const std::vector<Eigen::Vector3d>& normals,
                        const VoxelMap& map, const Eigen::Isometry3d& T, double max_distance_m, double inlier_m) {
  FitQuality f;
  const Eigen::Matrix3d R = T.rotation();
  const double gate2 = max_distance_m * max_distance_m;
  double sum2 = 0;
  Eigen::Vector3d q;
  double d2 = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (normals[i].squaredNorm() < 0.5) continue;
    ++f.points;
    const Eigen::Vector3d pw = T * pts[i];
    if (!map.nearest(pw, q, d2, gate2)) continue;
    const double e = (R * normals[i]).dot(pw - q);
    if (std::abs(e) >= inlier_m) continue;
    ++f.inliers;
    sum2 += e * e;
  }
  f.inlier_fraction = f.points > 0 ? static_cast<double>(f.inliers) / f.points : 0.0;
  f.inlier_rms = f.inliers > 0 ? std::sqrt(sum2 / f.inliers) : 0.0;
  return f;
}

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
