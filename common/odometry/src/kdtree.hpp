// The k-d tree over a point vector shared by the odometry's neighbour searches (nanoflann).
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

using KdTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, CloudAdaptor>, CloudAdaptor, 3, size_t>;

}  // namespace cdc::odometry::detail
