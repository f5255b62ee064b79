// Point-to-plane registration onto a voxel map, and the fit of a registered sweep.
#include "cdc/odometry/registration.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/normals.hpp"
#include "registration_detail.hpp"

#include <cmath>
#include <limits>

namespace cdc::odometry {

namespace {

// Gauss-Newton iterations from `initial`, unjudged.
RegistrationResult iterate(const std::vector<Eigen::Vector3d>& pts, const std::vector<Eigen::Vector3d>& normals,
                           const VoxelMap& map, const Eigen::Isometry3d& initial, const RegistrationSettings& s) {
  RegistrationResult out;
  out.T_target_source = initial;
  const double gate2 = s.max_correspondence_m * s.max_correspondence_m;
  const double k2 = s.kernel_m * s.kernel_m;
  for (int it = 0; it < s.max_iterations; ++it) {
    Matrix6d H = Matrix6d::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    const Eigen::Matrix3d R = out.T_target_source.rotation();
    const Eigen::Vector3d t = out.T_target_source.translation();
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
      const double den = k2 + e * e;
      const double w = k2 * k2 / (den * den);  // Geman-McClure
      Eigen::Matrix<double, 1, 6> J;
      J.leftCols<3>() = nw.transpose() * R;
      J.rightCols<3>() = -nw.transpose() * R * geometry::hat(ps);
      H.noalias() += w * J.transpose() * J;
      b.noalias() += w * J.transpose() * e;
      ++n;
      sum2 += e * e;
    }
    if (!detail::gauss_newton_step(H, b, n, sum2, it, s, out)) return out;
  }
  detail::at_iteration_limit(s, out);
  return out;
}

// Each source point's distance to its nearest map point within `gate_m` (infinity beyond).
std::vector<double> distances_to(const VoxelMap& map, const std::vector<Eigen::Vector3d>& pts,
                                 const Eigen::Isometry3d& T, double gate_m) {
  std::vector<double> out(pts.size(), std::numeric_limits<double>::infinity());
  Eigen::Vector3d q;
  double d2 = 0;
  for (size_t i = 0; i < pts.size(); ++i) {
    if (map.nearest(T * pts[i], q, d2, gate_m * gate_m)) out[i] = std::sqrt(d2);
  }
  return out;
}

void judge(const std::vector<Eigen::Vector3d>& pts, const VoxelMap& map, const RegistrationSettings& s,
           RegistrationResult& r) {
  if (s.inlier_distance_m > 0) {
    detail::judge_overlap(distances_to(map, pts, r.T_target_source, s.inlier_distance_m), s.inlier_distance_m, r);
  }
  if (s.information_scale > 0) detail::judge_information(s.information_scale, r);
}

}  // namespace

RegistrationResult register_to_map(const std::vector<Eigen::Vector3d>& pts, const std::vector<Eigen::Vector3d>& normals,
                                   const VoxelMap& map, const Eigen::Isometry3d& initial,
                                   const RegistrationSettings& s) {
  RegistrationResult out = iterate(pts, normals, map, initial, s);
  judge(pts, map, s, out);
  return out;
}

namespace detail {

RegistrationResult register_point_to_plane(const std::vector<Eigen::Vector3d>& source,
                                           const std::vector<Eigen::Vector3d>& target, const Eigen::Isometry3d& initial,
                                           const RegistrationSettings& s) {
  VoxelMap map(VoxelMapParams{s.map_voxel_m, 1000.0, 20});  // no pruning: one target cloud
  map.add(voxel_filter(target, s.target_voxel_m));
  const std::vector<Eigen::Vector3d> src = voxel_filter(source, s.voxel_m);
  const std::vector<Eigen::Vector3d> normals = knn_normals(src, source, s.neighbours, s.normal_radius_m);
  RegistrationResult out;
  out.T_target_source = initial;
  RegistrationSettings stage = s;
  for (const double gate : s.gates_m) {
    stage.max_correspondence_m = gate;
    stage.kernel_m = gate / 3;
    out = iterate(src, normals, map, out.T_target_source, stage);
  }
  judge(src, map, s, out);
  return out;
}

}  // namespace detail

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

}  // namespace cdc::odometry
