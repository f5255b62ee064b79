// The pose-graph model of cdc-slam: keyed SE(3) poses and prior / odometry / loop factors with
// 6x6 information over (tx, ty, tz, rx, ry, rz).
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <vector>

namespace cdc::graph {

using Key = uint64_t;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

// Robot in the top byte, keyframe index below: (robot << 56) | index.
constexpr Key make_key(uint32_t robot, uint64_t index) { return (uint64_t{robot} << 56) | index; }
constexpr uint32_t robot_of(Key key) { return static_cast<uint32_t>(key >> 56); }
constexpr uint64_t index_of(Key key) { return key & ((uint64_t{1} << 56) - 1); }

enum class FactorKind { kPrior, kOdometry, kLoop };

struct Factor {
  FactorKind kind = FactorKind::kLoop;
  Key a = 0;                                                      // for a prior: the constrained pose
  Key b = 0;                                                      // for a prior: equal to a
  Eigen::Isometry3d measurement = Eigen::Isometry3d::Identity();  // T_a_b, or T_world_a for a prior
  Matrix6d information = Matrix6d::Identity();
  bool robust = false;  // robust loss (loop closures)
  bool inter_robot() const { return robot_of(a) != robot_of(b); }
};

struct PoseGraph {
  std::map<Key, Eigen::Isometry3d> poses;  // current estimate T_world_key
  std::vector<Factor> factors;
  int dimension = 3;         // 2 for planar graphs lifted into 3D
  bool symbol_keys = false;  // read from GTSAM-symbol keys (('a' + robot) << 56 | index)

  void add_prior(Key key, const Eigen::Isometry3d& T_world_key, const Matrix6d& information);
  // Between factor; kind is odometry when b follows a on the same robot, loop otherwise.
  void add_between(Key a, Key b, const Eigen::Isometry3d& T_a_b, const Matrix6d& information);
  size_t count(FactorKind kind) const;
};

// Loop closures through one keyframe are registrations against the same cloud, so their errors are
// correlated: taken as independent measurements, n of them outweigh the odometry about n-fold.
// loop_counts gives, per key, the number of loop factors it takes part in.
std::map<Key, int> loop_counts(const PoseGraph& graph);
// Divides each loop factor's information by n, the larger count of its two keys in `counts`. Pass
// the counts of the whole graph when `graph` is a part of it (a local window).
void share_loop_information(PoseGraph& graph, const std::map<Key, int>& counts);
// The same for one factor (a loop; other factors are left as they are).
void share_loop_information(Factor& factor, const std::map<Key, int>& counts);
inline void share_loop_information(PoseGraph& graph) { share_loop_information(graph, loop_counts(graph)); }

// Where the robots' front-ends hold roll and pitch with gravity, the odometry's tilt does not drift,
// while a loop closure's tilt is the weakest part of its registration: two single sweeps of a sparse
// LiDAR seen from different places, each seeing the ground as rings (a miscalibrated one as a cone).
// level_information scales a between factor's information about the two horizontal axes by
// `tilt_scale` (0..1), in the level frame of its second keyframe b, where the rotation half of the
// residual is taken; `up_b` is up in b's frame. Yaw and translation keep their information.
Matrix6d level_information(const Matrix6d& information, const Eigen::Vector3d& up_b, double tilt_scale);
// The same for every loop factor of a graph whose world z is up, with up taken from the current
// estimate of each keyframe b (cdc-pgo --loop-tilt-scale, for graphs whose loops were not levelled).
void level_loop_information(PoseGraph& graph, double tilt_scale);

}  // namespace cdc::graph
