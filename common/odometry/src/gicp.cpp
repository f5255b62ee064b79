// Generalized ICP (Segal et al. 2009): plane-to-plane residuals on both clouds' covariances, each
// flattened to a plane through the point's neighbourhood.
#include "cdc/odometry/registration.hpp"

#include "cdc/geometry/se3.hpp"
#include "kdtree.hpp"
#include "registration_detail.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <limits>
#include <string>

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

std::vector<Eigen::Vector3d> to_double(const std::vector<Eigen::Vector3f>& pts) {
  std::vector<Eigen::Vector3d> out;
  out.reserve(pts.size());
  for (const auto& p : pts) out.push_back(p.cast<double>());
  return out;
}

std::vector<Eigen::Vector3d> reduced(std::vector<Eigen::Vector3d> points, double voxel_m) {
  return voxel_m > 0 ? voxel_centroids(points, voxel_m) : points;
}

}  // namespace

struct PreparedCloud::Impl {
  std::vector<Eigen::Vector3d> points;
  detail::CloudAdaptor adaptor{&points};
  detail::KdTree tree{3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10)};  // built by its constructor
  std::vector<Eigen::Matrix3d> covariances;
  Impl(std::vector<Eigen::Vector3d> p, int neighbours) : points(std::move(p)) {
    covariances = plane_covariances(points, tree, neighbours);
  }
};

PreparedCloud::PreparedCloud(const std::vector<Eigen::Vector3d>& points, const RegistrationSettings& s)
    : impl_(std::make_unique<Impl>(reduced(points, s.voxel_m), s.neighbours)) {}

PreparedCloud::PreparedCloud(const std::vector<Eigen::Vector3f>& points, const RegistrationSettings& s)
    : impl_(std::make_unique<Impl>(reduced(to_double(points), s.voxel_m), s.neighbours)) {}

PreparedCloud::~PreparedCloud() = default;
PreparedCloud::PreparedCloud(PreparedCloud&&) noexcept = default;
PreparedCloud& PreparedCloud::operator=(PreparedCloud&&) noexcept = default;

const std::vector<Eigen::Vector3d>& PreparedCloud::points() const { return impl_->points; }

RegistrationResult register_gicp(const PreparedCloud& source, const PreparedCloud& target,
                                 const Eigen::Isometry3d& initial, const RegistrationSettings& s) {
  RegistrationResult out;
  out.T_target_source = initial;
  const std::vector<Eigen::Vector3d>& src = source.points();
  const std::vector<Eigen::Vector3d>& tgt = target.points();
  if (src.size() < 20 || tgt.size() < 20) {
    out.warnings.push_back("too few points to register: " + std::to_string(src.size()) + " in the source, " +
                           std::to_string(tgt.size()) + " in the target (20 needed)");
    return out;
  }
  const std::vector<Eigen::Matrix3d>& cs = source.impl_->covariances;
  const std::vector<Eigen::Matrix3d>& ct = target.impl_->covariances;
  const detail::KdTree& ttree = target.impl_->tree;
  const double max2 = s.max_correspondence_m * s.max_correspondence_m;
  bool ended = false;
  for (int it = 0; it < s.max_iterations && !ended; ++it) {
    const Eigen::Matrix3d R = out.T_target_source.rotation();
    Matrix6d H = Matrix6d::Zero();
    Eigen::Matrix<double, 6, 1> b = Eigen::Matrix<double, 6, 1>::Zero();
    int n = 0;
    double sum2 = 0;
    for (size_t i = 0; i < src.size(); ++i) {
      const Eigen::Vector3d q = out.T_target_source * src[i];
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
    ended = !detail::gauss_newton_step(H, b, n, sum2, it, s, out);
  }
  if (!ended) detail::at_iteration_limit(s, out);
  if (s.inlier_distance_m > 0) {
    detail::judge_overlap(distances_to(ttree, src, out.T_target_source), s.inlier_distance_m, out);
  }
  if (s.information_scale > 0) detail::judge_information(s.information_scale, out);
  return out;
}

}  // namespace cdc::odometry
