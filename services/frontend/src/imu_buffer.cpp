#include "cdc/frontend/imu_buffer.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>

namespace cdc::frontend {

std::vector<std::optional<odometry::ImuDelta>> integrate_imu(const std::deque<ImuIn>& imu, int64_t from,
                                                             const std::vector<int64_t>& to, const Eigen::Vector3d& bg,
                                                             const Eigen::Vector3d& ba) {
  std::vector<std::optional<odometry::ImuDelta>> out(to.size());
  if (imu.size() < 2 || imu.front().stamp_ns > from) return out;
  odometry::ImuDelta inc;
  int64_t reached = from;
  size_t i = 0;
  for (size_t k = 0; k < to.size(); ++k) {
    if (imu.back().stamp_ns < to[k]) break;  // nor are later instants covered
    while (reached < to[k]) {
      while (imu[i + 1].stamp_ns <= reached) ++i;  // the sample held at `reached`
      const int64_t end = std::min(imu[i + 1].stamp_ns, to[k]);
      const double h = static_cast<double>(end - reached) * 1e-9;
      inc.step(geometry::so3_exp((imu[i].gyro - bg) * h), imu[i].accel - ba, h);
      reached = end;
    }
    out[k] = inc;
  }
  return out;
}

Eigen::Isometry3d lidar_motion(const odometry::ImuDelta& inc, const Eigen::Isometry3d& T_lidar_imu,
                               const ImuStart* start) {
  if (start == nullptr) {
    Eigen::Isometry3d R = Eigen::Isometry3d::Identity();
    R.linear() = T_lidar_imu.linear() * inc.R * T_lidar_imu.linear().transpose();
    return R;
  }
  Eigen::Isometry3d T_imu = Eigen::Isometry3d::Identity();
  T_imu.linear() = inc.R;
  T_imu.translation() = start->velocity * inc.dt + 0.5 * start->gravity * inc.dt * inc.dt + inc.p;
  return T_lidar_imu * T_imu * T_lidar_imu.inverse(Eigen::Isometry);
}

bool ImuBuffer::add(const ImuIn& s, int64_t latest_sweep_ns) {
  if (!samples_.empty() && s.stamp_ns <= samples_.back().stamp_ns) return false;
  samples_.push_back(s);
  while (samples_.size() > 2 && samples_[1].stamp_ns < latest_sweep_ns - 500'000'000) samples_.pop_front();
  return true;
}

std::unique_ptr<odometry::ImuPreintegration> ImuBuffer::preintegrate(int64_t from, int64_t to,
                                                                     const Eigen::Vector3d& bg,
                                                                     const Eigen::Vector3d& ba,
                                                                     const odometry::ImuNoiseParams& noise) const {
  if (samples_.size() < 2 || samples_.front().stamp_ns > from || samples_.back().stamp_ns < to || to <= from)
    return nullptr;
  auto pre = std::make_unique<odometry::ImuPreintegration>(bg, ba, noise);
  for (size_t i = 0; i + 1 < samples_.size(); ++i) {
    const int64_t a = std::max(samples_[i].stamp_ns, from), b = std::min(samples_[i + 1].stamp_ns, to);
    if (b > a) pre->integrate(samples_[i].gyro, samples_[i].accel, static_cast<double>(b - a) * 1e-9);
  }
  return pre;
}

std::optional<Eigen::Matrix3d> ImuBuffer::lidar_rotation(int64_t from, int64_t to, const Eigen::Vector3d& bg,
                                                         const Eigen::Isometry3d& T_lidar_imu) const {
  const auto inc = integrate_imu(samples_, from, {to}, bg, Eigen::Vector3d::Zero()).front();
  if (!inc) return std::nullopt;
  return lidar_motion(*inc, T_lidar_imu, nullptr).rotation();
}

}  // namespace cdc::frontend
