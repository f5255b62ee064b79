// Trajectory error metrics: ATE, RPE and the KITTI odometry drift metric.
// All take equally long vectors of already associated estimated and ground-truth poses.
#pragma once

#include "cdc/geometry/alignment.hpp"

#include <Eigen/Geometry>

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

namespace cdc::geometry {

using Poses = std::vector<Eigen::Isometry3d>;

enum class AlignMode { kNone, kSE3, kSim3 };
std::optional<AlignMode> parse_align_mode(const std::string& name);  // "none", "se3", "sim3"
const char* to_string(AlignMode mode);

struct ErrorStats {
  double rmse = 0, mean = 0, median = 0, std = 0, min = 0, max = 0;
  double p90 = 0;  // 90th percentile (nearest rank)
  size_t count = 0;
};
ErrorStats compute_stats(std::vector<double> values);

// Absolute trajectory error: translation error [m] after aligning est onto gt.
struct AteResult {
  ErrorStats translation;   // [m]
  ErrorStats rotation_deg;  // orientation error after alignment [deg]
  Alignment alignment;      // maps est into gt's frame
};
AteResult compute_ate(const Poses& est, const Poses& gt, AlignMode mode);

// Relative pose error between pairs (i, j): E = inv(inv(gt_i) gt_j) * inv(est_i) est_j.
struct RpeResult {
  ErrorStats translation;   // [m]
  ErrorStats rotation_deg;  // [deg]
  std::string delta;        // "1 frame", "100 m"
};
// Pairs (i, i + delta_frames).
RpeResult compute_rpe_frames(const Poses& est, const Poses& gt, size_t delta_frames);
// Pairs (i, j) with j the first pose whose ground-truth path distance from i reaches delta_m.
RpeResult compute_rpe_distance(const Poses& est, const Poses& gt, double delta_m);

// KITTI odometry benchmark drift: over all segments of 100, 200, ..., 800 m (start every
// step_frames frames), mean translational error in % of segment length and rotational error
// in deg per 100 m. segments == 0 when the trajectory is shorter than 100 m.
struct KittiDrift {
  double translation_pct = 0;
  double rotation_deg_per_100m = 0;
  size_t segments = 0;
};
KittiDrift compute_kitti_drift(const Poses& est, const Poses& gt, size_t step_frames = 10);

}  // namespace cdc::geometry
