#include "cdc/graph/pose_graph.hpp"

#include <algorithm>
#include <cmath>

namespace cdc::graph {

void PoseGraph::add_prior(Key key, const Eigen::Isometry3d& T_world_key, const Matrix6d& information) {
  Factor f;
  f.kind = FactorKind::kPrior;
  f.a = f.b = key;
  f.measurement = T_world_key;
  f.information = information;
  factors.push_back(f);
}

void PoseGraph::add_between(Key a, Key b, const Eigen::Isometry3d& T_a_b, const Matrix6d& information) {
  Factor f;
  const bool odometry = robot_of(a) == robot_of(b) && index_of(b) == index_of(a) + 1;
  f.kind = odometry ? FactorKind::kOdometry : FactorKind::kLoop;
  f.a = a;
  f.b = b;
  f.measurement = T_a_b;
  f.information = information;
  f.robust = !odometry;
  factors.push_back(f);
}

size_t PoseGraph::count(FactorKind kind) const {
  return static_cast<size_t>(
      std::count_if(factors.begin(), factors.end(), [&](const Factor& f) { return f.kind == kind; }));
}

std::map<Key, int> loop_counts(const PoseGraph& graph) {
  std::map<Key, int> counts;
  for (const Factor& f : graph.factors) {
    if (f.kind == FactorKind::kLoop) {
      ++counts[f.a];
      ++counts[f.b];
    }
  }
  return counts;
}

void share_loop_information(Factor& factor, const std::map<Key, int>& counts) {
  if (factor.kind != FactorKind::kLoop) return;
  auto count_of = [&](Key k) {
    const auto it = counts.find(k);
    return it == counts.end() ? 1 : std::max(it->second, 1);
  };
  factor.information /= static_cast<double>(std::max(count_of(factor.a), count_of(factor.b)));
}

void share_loop_information(PoseGraph& graph, const std::map<Key, int>& counts) {
  for (Factor& f : graph.factors) share_loop_information(f, counts);
}

Matrix6d level_information(const Matrix6d& information, const Eigen::Vector3d& up_b, double tilt_scale) {
  if (tilt_scale >= 1.0 || up_b.squaredNorm() == 0.0) {
    return information;
  }
  // The rotation half of a between factor's residual is taken in the frame of its second keyframe
  // (residuals.hpp); B turns it into that keyframe's level frame (z up), where the rows and columns
  // of rotation about x and y are scaled, and back. Translation is untouched.
  Matrix6d S = Matrix6d::Identity();
  S(3, 3) = S(4, 4) = std::sqrt(std::max(tilt_scale, 0.0));
  Matrix6d B = Matrix6d::Identity();
  B.bottomRightCorner<3, 3>() =
      Eigen::Quaterniond::FromTwoVectors(up_b.normalized(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Matrix6d level = S * (B * information * B.transpose()) * S;
  const Matrix6d out = B.transpose() * level * B;
  return 0.5 * (out + out.transpose());
}

void level_loop_information(PoseGraph& graph, double tilt_scale) {
  for (Factor& f : graph.factors) {
    const auto it = graph.poses.find(f.b);
    if (f.kind == FactorKind::kLoop && it != graph.poses.end()) {
      f.information =
          level_information(f.information, it->second.linear().transpose() * Eigen::Vector3d::UnitZ(), tilt_scale);
    }
  }
}

}  // namespace cdc::graph
