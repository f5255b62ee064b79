// Surface normals of a sweep's points, for point-to-plane registration and its fit test.
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace cdc::odometry {

// Normals of a sweep on its range image: `ring` per point (0 = lowest beam), azimuth from x, y.
// Each normal is the cross product of the neighbours along the ring and across the rings; points
// whose neighbours are missing, too far or not coplanar get a zero normal.
std::vector<Eigen::Vector3d> range_image_normals(const std::vector<Eigen::Vector3d>& points,
                                                 const std::vector<uint16_t>& rings, int columns = 1800,
                                                 double max_neighbour_m = 3.0);

// Normals for clouds without ring structure (a saved scan, a map): the smallest principal
// direction of each query point's k nearest neighbours in `cloud` (nanoflann k-d tree); zero
// when the neighbourhood is not planar or spans more than max_neighbour_m.
std::vector<Eigen::Vector3d> knn_normals(const std::vector<Eigen::Vector3d>& queries,
                                         const std::vector<Eigen::Vector3d>& cloud, int k = 10,
                                         double max_neighbour_m = 2.0);

}  // namespace cdc::odometry
