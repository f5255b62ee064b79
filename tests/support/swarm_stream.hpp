// A deterministic simulated stream of keyframes and loop closures for several robots, for tests
// and benchmarks of the back-ends before (and independently of) the front-end and loop closure.
// Robots drive laps of one city block (so they revisit each other's places), optionally with
// excursions far from the start; odometry and loops carry Gaussian noise.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace cdc::test {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

struct StreamKeyframe {
  uint32_t robot = 0;
  uint32_t id = 0;
  Eigen::Isometry3d T_odom_keyframe;  // noisy odometry, robot's odometry frame
  Eigen::Isometry3d T_prev_keyframe;  // noisy relative odometry from id - 1
  Matrix6d information;
  Eigen::Isometry3d T_world_truth;  // ground truth in W (robot 0's first odometry frame)
};

struct StreamLoop {
  uint32_t sender = 0;
  uint32_t seq = 0;
  uint32_t step = 0;  // produced when the sender's keyframe `step` is cut
  uint32_t robot_a = 0, keyframe_a = 0, robot_b = 0, keyframe_b = 0;
  Eigen::Isometry3d T_a_b;
  Matrix6d information;
};

struct SwarmStreamOptions {
  uint32_t robots = 3;
  uint32_t keyframes_per_robot = 200;
  uint32_t seed = 1;
  double spacing_m = 2.0;              // between keyframes
  double block_w = 120, block_h = 80;  // the lap [m]
  double odom_sigma_t = 0.02;          // [m] per keyframe
  double odom_sigma_r = 0.002;         // [rad] per keyframe
  double loop_radius_m = 4.0;          // true distance for a loop closure
  uint32_t loop_every = 3;             // at most one loop per robot every this many keyframes
  uint32_t min_loop_gap = 30;          // same-robot loops skip this many recent keyframes
  // Robot `excursion_robot` leaves the block along +x for excursion_m and comes back, every lap.
  int excursion_robot = -1;
  double excursion_m = 0;
};

struct SwarmStream {
  std::vector<std::vector<StreamKeyframe>> keyframes;  // [robot][id]
  std::vector<StreamLoop> loops;                       // in production order
  std::vector<Eigen::Isometry3d> T_world_odom;         // truth: robot's odometry frame in W
};

// The stream produced one step at a time without end (each step: one keyframe per robot and the
// loop closures they close), for feeders that run for hours. What it keeps grows by one position
// per keyframe (24 bytes), for the loop search. make_swarm_stream's first steps are the same.
class SwarmStreamGenerator {
 public:
  struct Step {
    std::vector<StreamKeyframe> keyframes;  // [robot]
    std::vector<StreamLoop> loops;
  };

  explicit SwarmStreamGenerator(const SwarmStreamOptions& options);
  Step next();
  uint32_t steps() const noexcept { return step_; }
  const std::vector<Eigen::Isometry3d>& T_world_odom() const noexcept { return T_world_odom_; }

 private:
  Eigen::Isometry3d truth(uint32_t robot, uint32_t k) const;
  bool find_loop(uint32_t robot, uint32_t k, StreamLoop& loop) const;

  SwarmStreamOptions o_;
  std::mt19937 rng_;
  Eigen::Isometry3d W_;  // robot 0's first pose, inverted
  Matrix6d odo_info_, loop_info_;
  std::vector<Eigen::Isometry3d> T_world_odom_;
  std::vector<std::vector<Eigen::Vector3d>> positions_;  // [robot][id] true positions in W
  std::vector<Eigen::Isometry3d> last_truth_, last_odom_;
  std::vector<uint32_t> seq_, last_loop_;
  uint32_t step_ = 0;
};

SwarmStream make_swarm_stream(const SwarmStreamOptions& options);

// A random rigid motion: translation drawn N(0, sigma_t) [m] per axis, rotation about x, y then z
// drawn N(0, sigma_r) [rad] each.
Eigen::Isometry3d pose_noise(std::mt19937& rng, double sigma_t, double sigma_r);

// Writes the whole stream as one g2o graph (keys robot << 56 | id; a prior is implicit on robot
// 0's first keyframe, which is the first vertex), with the odometry chain as initial values.
void write_stream_g2o(const SwarmStream& stream, const std::string& path);

}  // namespace cdc::test
