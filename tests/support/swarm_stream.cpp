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

SwarmStream make_swarm_stream(const SwarmStreamOptions& o) {
  std::mt19937 rng(o.seed);
  SwarmStream out;
  out.keyframes.resize(o.robots);
  const double lap = 2 * (o.block_w + o.block_h);
  std::vector<std::vector<Eigen::Isometry3d>> truth(o.robots);
  for (uint32_t r = 0; r < o.robots; ++r) {
    const double start = lap * r / (o.robots + 1.0);  // robots start spread along the lap
    for (uint32_t k = 0; k < o.keyframes_per_robot; ++k) {
      truth[r].push_back(path_pose(start + k * o.spacing_m, o, static_cast<int>(r) == o.excursion_robot));
    }
  }
  // W is robot 0's first pose.
  const Eigen::Isometry3d W = truth[0][0].inverse();
  for (auto& t : truth) {
    for (auto& T : t) {
      T = W * T;
    }
  }
  const Matrix6d odo_info = information(o.odom_sigma_t, o.odom_sigma_r);
  const Matrix6d loop_info = information(0.05, 0.005);
  for (uint32_t r = 0; r < o.robots; ++r) {
    out.T_world_odom.push_back(truth[r][0]);
  }
  std::vector<uint32_t> seq(o.robots, 0), last_loop(o.robots, 0);
  for (uint32_t k = 0; k < o.keyframes_per_robot; ++k) {
    for (uint32_t r = 0; r < o.robots; ++r) {
      StreamKeyframe kf;
      kf.robot = r;
      kf.id = k;
      kf.information = odo_info;
      kf.T_world_truth = truth[r][k];
      if (k == 0) {
        kf.T_prev_keyframe = Eigen::Isometry3d::Identity();
        kf.T_odom_keyframe = Eigen::Isometry3d::Identity();
      } else {
        kf.T_prev_keyframe = truth[r][k - 1].inverse() * truth[r][k] * pose_noise(rng, o.odom_sigma_t, o.odom_sigma_r);
        kf.T_odom_keyframe = out.keyframes[r][k - 1].T_odom_keyframe * kf.T_prev_keyframe;
      }
      out.keyframes[r].push_back(kf);
      // One loop closure from this keyframe to the closest earlier place, if any.
      if (k < last_loop[r] + o.loop_every && k >= o.loop_every) {
        continue;
      }
      double best = o.loop_radius_m;
      int best_r = -1, best_k = -1;
      for (uint32_t q = 0; q < o.robots; ++q) {
        const uint32_t limit = q == r ? (k > o.min_loop_gap ? k - o.min_loop_gap : 0) : (q < r ? k + 1 : k);
        for (uint32_t j = 0; j < limit; ++j) {
          const double d = (truth[q][j].translation() - truth[r][k].translation()).norm();
          if (d < best) {
            best = d;
            best_r = static_cast<int>(q);
            best_k = static_cast<int>(j);
          }
        }
      }
      if (best_r < 0) {
        continue;
      }
      StreamLoop l;
      l.sender = r;
      l.seq = seq[r]++;
      l.step = k;
      l.robot_a = static_cast<uint32_t>(best_r);
      l.keyframe_a = static_cast<uint32_t>(best_k);
      l.robot_b = r;
      l.keyframe_b = k;
      l.T_a_b = truth[l.robot_a][l.keyframe_a].inverse() * truth[r][k] * pose_noise(rng, 0.05, 0.005);
      l.information = loop_info;
      out.loops.push_back(l);
      last_loop[r] = k;
    }
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
