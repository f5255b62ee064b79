#include "swarm_stream.hpp"

#include <cmath>
#include <fstream>
#include <iomanip>
#include <random>
#include <stdexcept>

namespace cdc::test {
namespace {

// Position and heading at arc length s on a rectangular lap starting at the origin heading +x.
Eigen::Isometry3d lap_pose(double s, double w, double h) {
  const double perimeter = 2 * (w + h);
  s = std::fmod(s, perimeter);
  double x = 0, y = 0, yaw = 0;
  if (s < w) {
    x = s;
  } else if (s < w + h) {
    x = w, y = s - w, yaw = M_PI / 2;
  } else if (s < 2 * w + h) {
    x = w - (s - w - h), y = h, yaw = M_PI;
  } else {
    y = h - (s - 2 * w - h), yaw = -M_PI / 2;
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = Eigen::Vector3d(x, y, 0);
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

// A lap with an out-and-back excursion along -y from the lap's start, every lap.
Eigen::Isometry3d path_pose(double s, const SwarmStreamOptions& o, bool excursion) {
  if (!excursion || o.excursion_m <= 0) {
    return lap_pose(s, o.block_w, o.block_h);
  }
  const double lap = 2 * (o.block_w + o.block_h);
  const double period = lap + 2 * o.excursion_m;
  const double u = std::fmod(s, period);
  if (u < lap) {
    return lap_pose(u, o.block_w, o.block_h);
  }
  const double e = u - lap;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  const double out = e < o.excursion_m ? e : 2 * o.excursion_m - e;
  T.translation() = Eigen::Vector3d(0, -out, 0);
  T.linear() = Eigen::AngleAxisd(e < o.excursion_m ? -M_PI / 2 : M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return T;
}

Matrix6d information(double st, double sr) {
  Matrix6d I = Matrix6d::Zero();
  I.diagonal() << 1 / (st * st), 1 / (st * st), 1 / (st * st), 1 / (sr * sr), 1 / (sr * sr), 1 / (sr * sr);
  return I;
}

}  // namespace

Eigen::Isometry3d pose_noise(std::mt19937& rng, double sigma_t, double sigma_r) {
  std::normal_distribution<double> t(0, sigma_t), r(0, sigma_r);
  Eigen::Isometry3d N = Eigen::Isometry3d::Identity();
  N.linear() =
      (Eigen::AngleAxisd(r(rng), Eigen::Vector3d::UnitX()) * Eigen::AngleAxisd(r(rng), Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(r(rng), Eigen::Vector3d::UnitZ()))
          .toRotationMatrix();
  N.translation() = Eigen::Vector3d(t(rng), t(rng), t(rng));
  return N;
}

SwarmStreamGenerator::SwarmStreamGenerator(const SwarmStreamOptions& o)
    : o_(o),
      rng_(o.seed),
      W_(Eigen::Isometry3d::Identity()),
      odo_info_(information(o.odom_sigma_t, o.odom_sigma_r)),
      loop_info_(information(0.05, 0.005)),
      positions_(o.robots),
      last_truth_(o.robots),
      last_odom_(o.robots),
      seq_(o.robots, 0),
      last_loop_(o.robots, 0) {
  W_ = truth(0, 0).inverse();
  for (uint32_t r = 0; r < o.robots; ++r) {
    T_world_odom_.push_back(truth(r, 0));
  }
}

// Robot `robot`'s true pose in W at its keyframe k; robots start spread along the lap.
Eigen::Isometry3d SwarmStreamGenerator::truth(uint32_t robot, uint32_t k) const {
  const double lap = 2 * (o_.block_w + o_.block_h);
  const double start = lap * robot / (o_.robots + 1.0);
  return W_ * path_pose(start + k * o_.spacing_m, o_, static_cast<int>(robot) == o_.excursion_robot);
}

// The closest earlier place within loop_radius_m: every robot's keyframes so far (this step's of the
// robots before this one included), the robot's own recent ones excepted.
bool SwarmStreamGenerator::find_loop(uint32_t r, uint32_t k, StreamLoop& l) const {
  double best = o_.loop_radius_m;
  int best_r = -1, best_k = -1;
  const Eigen::Vector3d& here = positions_[r][k];
  for (uint32_t q = 0; q < o_.robots; ++q) {
    const uint32_t limit = q == r ? (k > o_.min_loop_gap ? k - o_.min_loop_gap : 0) : (q < r ? k + 1 : k);
    for (uint32_t j = 0; j < limit; ++j) {
      const double d = (positions_[q][j] - here).norm();
      if (d < best) {
        best = d;
        best_r = static_cast<int>(q);
        best_k = static_cast<int>(j);
      }
    }
  }
  if (best_r < 0) {
    return false;
  }
  l.robot_a = static_cast<uint32_t>(best_r);
  l.keyframe_a = static_cast<uint32_t>(best_k);
  return true;
}

SwarmStreamGenerator::Step SwarmStreamGenerator::next() {
  const uint32_t k = step_++;
  Step out;
  for (uint32_t r = 0; r < o_.robots; ++r) {
    const Eigen::Isometry3d T_true = truth(r, k);
    StreamKeyframe kf;
    kf.robot = r;
    kf.id = k;
    kf.information = odo_info_;
    kf.T_world_truth = T_true;
    if (k == 0) {
      kf.T_prev_keyframe = Eigen::Isometry3d::Identity();
      kf.T_odom_keyframe = Eigen::Isometry3d::Identity();
    } else {
      kf.T_prev_keyframe = last_truth_[r].inverse() * T_true * pose_noise(rng_, o_.odom_sigma_t, o_.odom_sigma_r);
      kf.T_odom_keyframe = last_odom_[r] * kf.T_prev_keyframe;
    }
    last_truth_[r] = T_true;
    last_odom_[r] = kf.T_odom_keyframe;
    positions_[r].push_back(T_true.translation());
    out.keyframes.push_back(kf);
    // At most one loop closure every loop_every keyframes per robot.
    StreamLoop l;
    if ((k < last_loop_[r] + o_.loop_every && k >= o_.loop_every) || !find_loop(r, k, l)) {
      continue;
    }
    l.sender = r;
    l.seq = seq_[r]++;
    l.step = k;
    l.robot_b = r;
    l.keyframe_b = k;
    const Eigen::Isometry3d T_a = truth(l.robot_a, l.keyframe_a);
    l.T_a_b = T_a.inverse() * T_true * pose_noise(rng_, 0.05, 0.005);
    l.information = loop_info_;
    out.loops.push_back(l);
    last_loop_[r] = k;
  }
  return out;
}

SwarmStream make_swarm_stream(const SwarmStreamOptions& o) {
  SwarmStreamGenerator gen(o);
  SwarmStream out;
  out.keyframes.resize(o.robots);
  out.T_world_odom = gen.T_world_odom();
  for (uint32_t k = 0; k < o.keyframes_per_robot; ++k) {
    SwarmStreamGenerator::Step step = gen.next();
    for (auto& kf : step.keyframes) {
      out.keyframes[kf.robot].push_back(kf);
    }
    out.loops.insert(out.loops.end(), step.loops.begin(), step.loops.end());
  }
  return out;
}

void write_stream_g2o(const SwarmStream& s, const std::string& path) {
  std::ofstream out(path);
  if (!out) {
    throw std::runtime_error(path + ": cannot create file");
  }
  out << std::setprecision(17);
  auto key = [](uint32_t r, uint32_t id) { return (uint64_t{r} << 56) | id; };
  auto edge = [&](uint64_t a, uint64_t b, const Eigen::Isometry3d& T, const Matrix6d& I) {
    const Eigen::Quaterniond q(T.rotation());
    out << "EDGE_SE3:QUAT " << a << ' ' << b << ' ' << T.translation().x() << ' ' << T.translation().y() << ' '
        << T.translation().z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w();
    for (int i = 0; i < 6; ++i) {
      for (int j = i; j < 6; ++j) {
        out << ' ' << I(i, j);
      }
    }
    out << '\n';
  };
  for (const auto& robot : s.keyframes) {
    for (const auto& kf : robot) {
      const Eigen::Isometry3d T = s.T_world_odom[kf.robot] * kf.T_odom_keyframe;
      const Eigen::Quaterniond q(T.rotation());
      out << "VERTEX_SE3:QUAT " << key(kf.robot, kf.id) << ' ' << T.translation().x() << ' ' << T.translation().y()
          << ' ' << T.translation().z() << ' ' << q.x() << ' ' << q.y() << ' ' << q.z() << ' ' << q.w() << '\n';
    }
  }
  for (const auto& robot : s.keyframes) {
    for (const auto& kf : robot) {
      if (kf.id > 0) {
        edge(key(kf.robot, kf.id - 1), key(kf.robot, kf.id), kf.T_prev_keyframe, kf.information);
      }
    }
  }
  for (const auto& l : s.loops) {
    edge(key(l.robot_a, l.keyframe_a), key(l.robot_b, l.keyframe_b), l.T_a_b, l.information);
  }
}

}  // namespace cdc::test
