// Evaluation of estimated trajectories against ground truth: association by time stamp,
// ATE/RPE/KITTI drift, JSON and text reports, SVG plots (top view).
#pragma once

#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>
#include <vector>

namespace cdc::eval {

struct EvalOptions {
  geometry::AlignMode align = geometry::AlignMode::kSE3;
  int64_t max_dt_ns = 10'000'000;  // association tolerance
  size_t rpe_delta_frames = 1;
  double rpe_delta_m = 100.0;
};

struct Evaluation {
  std::string name;
  size_t estimated_poses = 0;
  size_t ground_truth_poses = 0;
  size_t matched = 0;
  double gt_length_m = 0.0;
  geometry::AteResult ate;
  geometry::RpeResult rpe_frames;
  geometry::RpeResult rpe_distance;
  geometry::KittiDrift drift;
  geometry::Poses est_aligned;  // matched estimate after alignment
  geometry::Poses gt_matched;
};

// Throws std::runtime_error when fewer than 2 poses match in time.
Evaluation evaluate(const std::string& name, const geometry::Trajectory& est, const geometry::Trajectory& gt,
                    const EvalOptions& options);

nlohmann::json to_json(const Evaluation& e, const EvalOptions& options);

// Aligned text table, one row per evaluation.
std::string format_table(const std::vector<Evaluation>& evaluations);

// Top-view SVG of every estimate (aligned) against ground truth. plane: "xy", "xz", "yz" or
// "auto" (the two axes along which the ground truth extends most).
// The colour of the k-th estimate in the plots (cycles through a small palette).
const char* plot_color(size_t k);

// A point of interest drawn over the plot, in the ground truth's frame (e.g. where a robot
// switched mode): a triangle or a circle with a short label.
struct SvgMarker {
  Eigen::Vector3d position = Eigen::Vector3d::Zero();
  bool triangle = true;
  std::string color = "#000000";
  std::string label;
};

std::string render_svg(const std::vector<Evaluation>& evaluations, const std::string& plane, const std::string& title,
                       const std::vector<SvgMarker>& markers = {}, const std::string& marker_legend = "");

}  // namespace cdc::eval
