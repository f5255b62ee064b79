// The loop-closure service's synchronous core: Scan Context retrieval over every robot's keyframes,
// geometric verification (GICP from the descriptor's yaw), and PCM over each robot pair's
// inter-robot loops. Decisions are stable: a published loop is only ever retracted explicitly.
#pragma once

#include "cdc/graph/pcm.hpp"
#include "cdc/graph/pose_graph.hpp"
#include "cdc/lidar/registration.hpp"
#include "cdc/lidar/scan_context.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <set>
#include <vector>

namespace cdc::loops {

struct LoopParams {
  lidar::ScanContextParams scan_context;
  size_t knn = 10;                 // ring-key neighbours examined
  double max_sc_distance = 0.35;   // Scan Context distance for a candidate
  uint32_t exclude_recent = 50;    // same-robot keyframes too recent to close a loop with
  size_t max_verify = 2;           // candidates verified per keyframe
  lidar::RegistrationParams registration;
  double max_fitness = 0.15;       // [m^2] mean squared inlier distance
  double min_overlap = 0.55;
  graph::PcmOptions pcm;
};

struct KeyframeIn {
  uint32_t robot = 0, id = 0;
  Eigen::Isometry3d T_prev = Eigen::Isometry3d::Identity();  // relative odometry from id - 1
  graph::Matrix6d information = graph::Matrix6d::Identity();
  std::vector<Eigen::Vector3f> cloud;                          // keyframe frame, sensor at the origin
};

struct LoopOut {
  uint32_t robot_a = 0, keyframe_a = 0, robot_b = 0, keyframe_b = 0;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  graph::Matrix6d information = graph::Matrix6d::Identity();
  double fitness = 0;
  bool withdrawn = false;
};

struct LoopStats {
  uint64_t queries = 0, candidates = 0, verified = 0, verification_failed = 0;
  uint64_t intra_accepted = 0, intra_inconsistent = 0, inter_proposed = 0, inter_accepted = 0, withdrawn = 0;
};

class LoopCore {
 public:
  explicit LoopCore(const LoopParams& params);

  // Adds a keyframe, searches loops from it to earlier keyframes (any robot), and returns newly
  // accepted loops and withdrawals.
  std::vector<LoopOut> add_keyframe(KeyframeIn kf);

  const LoopStats& stats() const noexcept { return stats_; }
  size_t keyframes() const noexcept { return db_.size(); }
  const lidar::ScanContextDatabase& database() const noexcept { return db_; }

 private:
  std::vector<LoopOut> update_pcm(uint32_t robot_a, uint32_t robot_b);

  LoopParams p_;
  lidar::ScanContextDatabase db_;
  std::vector<std::pair<uint32_t, uint32_t>> owner_;          // db id -> (robot, keyframe)
  std::map<std::pair<uint32_t, uint32_t>, std::vector<Eigen::Vector3f>> clouds_;  // downsampled
  graph::PoseGraph odometry_;                                   // odometry of every robot + inter loops
  std::map<std::pair<uint32_t, uint32_t>, std::vector<size_t>> inter_;  // robot pair -> factor ids
  std::map<size_t, LoopOut> proposed_;                          // factor id -> loop
  std::set<size_t> published_;                                  // factor ids accepted and published
  LoopStats stats_;
};

}  // namespace cdc::loops
