// The k-d tree over a point vector shared by the odometry's neighbour searches (nanoflann), and the
// scatter of a neighbourhood it found (normals and GICP covariances both start from it).
#pragma once

#include <Eigen/Core>
#include <nanoflann.hpp>

#include <vector>

namespace cdc::odometry::detail {

struct CloudAdaptor {
  const std::vector<Eigen::Vector3d>* pts;
  size_t kdtree_get_point_count() const { return pts->size(); }
  double kdtree_get_pt(size_t i, size_t dim) const { return (*pts)[i][static_cast<Eigen::Index>(dim)]; }
  template <class BBox>
  bool kdtree_get_bbox(BBox&) const {
    return false;
  }
};

using KdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, CloudAdaptor>, CloudAdaptor, 3, size_t>;

// Sum of (p - mean)(p - mean)^T over cloud[idx[0..n)].
inline Eigen::Matrix3d neighbour_scatter(const std::vector<Eigen::Vector3d>& cloud, const size_t* idx, size_t n) {
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (size_t j = 0; j < n; ++j) mean += cloud[idx[j]];
  mean /= static_cast<double>(n);
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (size_t j = 0; j < n; ++j) {
    const Eigen::Vector3d v = cloud[idx[j]] - mean;
    scatter += v * v.transpose();
  }
  return scatter;
}

}  // namespace cdc::odometry::detail
