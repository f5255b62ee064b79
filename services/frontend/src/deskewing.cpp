#include "cdc/frontend/deskewing.hpp"

#include "cdc/geometry/se3.hpp"
#include "cdc/odometry/normals.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <algorithm>
#include <cmath>

namespace cdc::frontend {

float latest_point_time(const std::vector<ScanPoint>& points) {
  float t_max = 0;
  for (const auto& pt : points) t_max = std::max(t_max, pt.time_offset);
  return t_max;
}

Deskewer::Deskewer(const FrontendParams& params) : p_(params) {}

Eigen::Isometry3d Deskewer::motion_over(const Eigen::Isometry3d& D, float t_max, double dt) {
  return geometry::se3_exp(geometry::se3_log(D) * (static_cast<double>(t_max) / dt));
}

bool Deskewer::in_range(const Eigen::Vector3d& p) const {
  const double r2 = p.squaredNorm();
  return r2 >= p_.min_range_m * p_.min_range_m && r2 <= p_.max_range_m * p_.max_range_m;
}

Deskewer::Slots Deskewer::motion_slots(int64_t stamp_ns, double span, const Eigen::Isometry3d& sweep_motion,
                                       const DeskewImu& imu) const {
  Slots slot;
  const geometry::Vector6d xi = geometry::se3_log(sweep_motion);  // over `span`
  std::vector<int64_t> instants(kSlots + 1);
  for (int k = 0; k <= kSlots; ++k) {
    const double f = static_cast<double>(k) / kSlots;
    slot[static_cast<size_t>(k)] = geometry::se3_exp(xi * f);
    instants[static_cast<size_t>(k)] = stamp_ns + static_cast<int64_t>(f * span * 1e9);
  }
  if (imu.imu == nullptr || imu.imu->empty()) return slot;
  // The IMU's motion where it covers: all of it with the start state, else its rotation.
  const auto inc = imu.imu->increments(stamp_ns, instants, imu.gyro_bias, imu.accel_bias);  // one pass for all slots
  for (size_t k = 0; k < inc.size(); ++k) {
    if (!inc[k]) continue;
    const Eigen::Isometry3d m = lidar_motion(*inc[k], p_.T_lidar_imu, imu.start);
    if (imu.start != nullptr) {
      slot[k] = m;
    } else {
      slot[k].linear() = m.linear();
    }
  }
  return slot;
}

std::vector<Eigen::Vector3d> Deskewer::deskew(int64_t stamp_ns, const std::vector<ScanPoint>& points,
                                              const Eigen::Isometry3d& sweep_motion, const DeskewImu& imu,
                                              std::vector<uint16_t>& rings) const {
  const float t_max = latest_point_time(points);
  const bool deskew = p_.deskew && t_max > 0;  // a sweep without per-point times (all zero) is taken as it is
  const double span = std::max(1e-3, static_cast<double>(t_max));
  Slots slot;
  if (deskew) slot = motion_slots(stamp_ns, span, sweep_motion, imu);
  std::vector<Eigen::Vector3d> out;
  out.reserve(points.size());
  rings.clear();
  rings.reserve(points.size());
  for (const auto& pt : points) {
    const Eigen::Vector3d p = pt.p.cast<double>();
    if (!in_range(p)) continue;
    rings.push_back(pt.ring);
    if (!deskew) {
      out.push_back(p);
      continue;
    }
    // Moved into the sensor frame at the sweep's start with the motion at the nearest instant.
    const int k = std::clamp(static_cast<int>(std::lround(pt.time_offset / span * kSlots)), 0, kSlots);
    out.push_back(slot[static_cast<size_t>(k)] * p);
  }
  return out;
}

Sweep Deskewer::prepare(int64_t stamp_ns, const std::vector<ScanPoint>& points, const Eigen::Isometry3d& sweep_motion,
                        const DeskewImu& imu) const {
  std::vector<uint16_t> rings;
  std::vector<Eigen::Vector3d> cloud = deskew(stamp_ns, points, sweep_motion, imu, rings);
  const bool has_rings = std::any_of(rings.begin(), rings.end(), [](uint16_t r) { return r != 0; });
  return has_rings ? select_on_rings(std::move(cloud), rings) : select_by_neighbours(std::move(cloud));
}

Sweep Deskewer::select_on_rings(std::vector<Eigen::Vector3d> cloud, const std::vector<uint16_t>& rings) const {
  Sweep sw;
  sw.cloud = std::move(cloud);
  const std::vector<size_t> keep = odometry::voxel_filter_indices(sw.cloud, p_.voxel_m);
  const std::vector<Eigen::Vector3d> all_normals = odometry::range_image_normals(sw.cloud, rings, p_.image_columns);
  for (size_t i : keep) {
    if (all_normals[i].squaredNorm() < 0.5) continue;
    sw.points.push_back(sw.cloud[i]);
    sw.normals.push_back(all_normals[i]);
  }
  return sw;
}

// No ring structure (a saved KITTI sweep): normals from each point's nearest neighbours, in the
// sweep reduced to one point per normal_voxel_m voxel (which the rest of the sweep's use takes
// too): the k-d tree is built on a fraction of a dense sweep's points, and a near point's
// neighbours spread over several rings instead of lying on its own.
Sweep Deskewer::select_by_neighbours(std::vector<Eigen::Vector3d> cloud) const {
  Sweep sw;
  sw.cloud = p_.normal_voxel_m > 0 ? odometry::voxel_filter(cloud, p_.normal_voxel_m) : std::move(cloud);
  const std::vector<Eigen::Vector3d> sel = odometry::voxel_filter(sw.cloud, p_.voxel_m);
  const std::vector<Eigen::Vector3d> n = odometry::knn_normals(sel, sw.cloud, 10, 1.5);
  for (size_t i = 0; i < sel.size(); ++i) {
    if (n[i].squaredNorm() < 0.5) continue;
    sw.points.push_back(sel[i]);
    sw.normals.push_back(n[i]);
  }
  return sw;
}

}  // namespace cdc::frontend
