// The lidar library's only translation unit that includes PCL.
#include "cdc/lidar/registration.hpp"

#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/registration/gicp.h>

#include <algorithm>

namespace cdc::lidar {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

Cloud::Ptr to_pcl(const std::vector<Eigen::Vector3f>& pts) {
  Cloud::Ptr c(new Cloud);
  c->reserve(pts.size());
  for (const auto& p : pts) {
    c->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  }
  c->width = static_cast<uint32_t>(c->size());
  c->height = 1;
  return c;
}

Cloud::Ptr downsample(const Cloud::Ptr& in, double voxel) {
  if (voxel <= 0) return in;
  Cloud::Ptr out(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> vg;
  vg.setInputCloud(in);
  const float v = static_cast<float>(voxel);
  vg.setLeafSize(v, v, v);
  vg.filter(*out);
  return out;
}

}  // namespace

std::vector<Eigen::Vector3f> voxel_downsample(const std::vector<Eigen::Vector3f>& points, double voxel_m) {
  const Cloud::Ptr c = downsample(to_pcl(points), voxel_m);
  std::vector<Eigen::Vector3f> out;
  out.reserve(c->size());
  for (const auto& p : *c) out.emplace_back(p.x, p.y, p.z);
  return out;
}

RegistrationResult register_clouds(const std::vector<Eigen::Vector3f>& source, const std::vector<Eigen::Vector3f>& target,
                                   const Eigen::Isometry3d& initial, const RegistrationParams& p) {
  RegistrationResult r;
  const Cloud::Ptr src = downsample(to_pcl(source), p.voxel_m);
  const Cloud::Ptr tgt = downsample(to_pcl(target), p.voxel_m);
  if (src->size() < 20 || tgt->size() < 20) {
    return r;
  }
  pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> gicp;
  gicp.setInputSource(src);
  gicp.setInputTarget(tgt);
  gicp.setMaxCorrespondenceDistance(p.max_correspondence_m);
  gicp.setMaximumIterations(p.max_iterations);
  gicp.setTransformationEpsilon(1e-6);
  gicp.setEuclideanFitnessEpsilon(1e-6);
  Cloud aligned;
  gicp.align(aligned, initial.matrix().cast<float>());
  r.converged = gicp.hasConverged();
  r.T_target_source.matrix() = gicp.getFinalTransformation().cast<double>();
  // Fitness and overlap over inliers.
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(tgt);
  std::vector<int> idx(1);
  std::vector<float> d2(1);
  double sum = 0;
  size_t inliers = 0;
  const double lim2 = p.inlier_distance_m * p.inlier_distance_m;
  for (const auto& q : aligned) {
    if (tree.nearestKSearch(q, 1, idx, d2) == 1 && d2[0] <= lim2) {
      sum += d2[0];
      ++inliers;
    }
  }
  r.overlap = static_cast<double>(inliers) / static_cast<double>(aligned.size());
  r.fitness = inliers > 0 ? sum / static_cast<double>(inliers) : 1e9;
  // Information: isotropic, from the residual spread (floored so that a perfect fit is not infinite).
  const double sigma2 = std::max(r.fitness, 1e-3);
  r.information = Eigen::Matrix<double, 6, 6>::Identity();
  r.information.topLeftCorner<3, 3>() *= 1.0 / sigma2;
  r.information.bottomRightCorner<3, 3>() *= 1.0 / (sigma2 * 1e-2);  // ~0.1 rad per metre of residual
  return r;
}

}  // namespace cdc::lidar
