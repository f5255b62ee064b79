// Precision and recall of loop closures against ground truth, shared by cdc-loops and
// cdc-bench-loops. A loop is true when its relative pose is within max_error of the truth; a
// keyframe is a true revisit when an earlier keyframe (any robot; of its own robot only outside
// the `exclude_recent` most recent ones) lies within revisit_m; a revisit is recalled when some
// true accepted loop joins it to an earlier keyframe (either way round).
#pragma once

#include "cdc/loop_closure/loop_core.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace cdc::loops {

struct TruthKeyframe {
  uint32_t robot = 0, id = 0;
  Eigen::Isometry3d T_world = Eigen::Isometry3d::Identity();
};

struct EvaluationOptions {
  double max_error_m = 1.0, max_error_deg = 5.0;
  double revisit_m = 5.0;
  uint32_t exclude_recent = 50;
};

struct LoopVerdict {
  LoopOut loop;
  double error_m = 0, error_deg = 0;
  bool correct = false;
};

struct LoopEvaluation {
  std::vector<LoopVerdict> loops;  // every accepted loop, judged
  size_t true_positives = 0, false_intra = 0, false_inter = 0;
  size_t revisits = 0, recalled = 0;
  std::vector<std::pair<uint32_t, uint32_t>> missed;  // revisits not recalled (robot, keyframe)
  double precision() const;
  double recall() const;
};

// `order`: every keyframe in processing order; `accepted`: the loops standing at the end.
LoopEvaluation evaluate_loops(const std::vector<TruthKeyframe>& order, const std::vector<LoopOut>& accepted,
                              const EvaluationOptions& options);

}  // namespace cdc::loops
