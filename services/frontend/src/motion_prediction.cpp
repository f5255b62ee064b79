#include "cdc/frontend/motion_prediction.hpp"

#include "cdc/geometry/se3.hpp"

namespace cdc::frontend {

MotionPredictor::MotionPredictor(const FrontendParams& params) : p_(params) {}

Prediction MotionPredictor::predict(int64_t last_ns, int64_t stamp_ns, double dt, const ImuBuffer& imu,
                                    FrontendStats& stats) const {
  Prediction out;
  Eigen::Isometry3d delta = geometry::se3_exp(geometry::se3_log(delta_) * (dt / dt_last_));
  // The IMU since the previous sweep, at the window's biases: for the prediction and the window.
  if (window_) {
    const ImuState st = window_->ready() ? window_->latest() : ImuState{};
    out.pre = imu.preintegrate(last_ns, stamp_ns, st.bg, st.ba, p_.window.noise);
  }
  if (window_ && window_->ready() && out.pre) {
    if (const auto d = window_prediction(*out.pre, delta, out, stats)) {
      out.delta = *d;
      return out;
    }
  }
  if (const auto R = imu.lidar_rotation(last_ns, stamp_ns, gyro_bias_, p_.T_lidar_imu)) delta.linear() = *R;
  out.delta = delta;
  return out;
}

std::optional<Eigen::Isometry3d> MotionPredictor::window_prediction(const odometry::ImuPreintegration& pre,
                                                                    const Eigen::Isometry3d& delta, Prediction& out,
                                                                    FrontendStats& stats) const {
  // The motion the IMU predicts from the window's latest pose, applied to the registered one.
  const Eigen::Isometry3d d = window_->latest_lidar().inverse() * window_->predict_lidar(pre);
  const Eigen::Isometry3d gap = delta.inverse() * d;
  const bool plausible = d.matrix().allFinite() && gap.translation().norm() <= p_.max_imu_prediction_gap_m &&
                         geometry::rotation_angle(gap.rotation()) <= p_.max_imu_prediction_gap_rad;
  if (!plausible) {
    ++stats.imu_predictions_rejected;
    return std::nullopt;
  }
  ++stats.imu_predictions;
  if (p_.imu_deskew) {
    const ImuState next = window_->predict(pre);
    const Eigen::Matrix3d Rt = next.q.toRotationMatrix().transpose();
    out.imu_start = ImuStart{Rt * next.v, Rt * window_->gravity()};
  }
  return d;
}

void MotionPredictor::record_motion(const Eigen::Isometry3d& delta, double dt) {
  delta_ = delta;
  dt_last_ = dt;
}

void MotionPredictor::update_window(int64_t stamp_ns, const Eigen::Isometry3d& T,
                                    const odometry::RegistrationResult& reg,
                                    std::unique_ptr<odometry::ImuPreintegration> pre, const ImuBuffer& imu,
                                    FrontendStats& stats) {
  if (!p_.imu_window || imu.empty()) return;
  if (!window_) window_ = std::make_unique<ImuWindow>(p_.window, p_.T_lidar_imu);
  const Matrix6d info = reg.converged && reg.correspondences > 0 ? Matrix6d(reg.hessian * p_.information_scale)
                                                                 : Matrix6d(Matrix6d::Identity());
  const uint64_t restarts = window_->restarts();
  window_->add(stamp_ns, T, info, std::move(pre));
  stats.imu_window_restarts += window_->restarts() - restarts;
  gyro_bias_ = window_->ready() ? window_->latest().bg : Eigen::Vector3d::Zero();
}

DeskewImu MotionPredictor::deskew_imu(const ImuBuffer& imu, const ImuStart* start) const {
  const Eigen::Vector3d ba = start != nullptr && window_ ? window_->latest().ba : Eigen::Vector3d::Zero();
  return DeskewImu{&imu, gyro_bias_, ba, start};
}

std::optional<ImuState> MotionPredictor::imu_state() const {
  if (!window_ || !window_->ready()) return std::nullopt;
  return window_->latest();
}

std::optional<Eigen::Vector3d> MotionPredictor::running_gravity() const {
  if (!window_ || !window_->ready()) return std::nullopt;
  return window_->gravity();
}

std::optional<Eigen::Vector3d> MotionPredictor::gravity() const {
  if (!window_ || !window_->gravity_known()) return std::nullopt;
  return window_->gravity();
}

}  // namespace cdc::frontend
