#include "cdc/frontend/frontend_core.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

namespace cdc::frontend {
namespace {

using geometry::Vector6d;

double angle_of(const Eigen::Isometry3d& T) { return geometry::rotation_angle(T.rotation()); }

}  // namespace

FrontendCore::FrontendCore(const FrontendParams& params) : p_(params), map_(params.map) {}

void FrontendCore::add_imu(const ImuIn& s) {
  if (!imu_.empty() && s.stamp_ns <= imu_.back().stamp_ns) return;
  imu_.push_back(s);
  ++stats_.imu_samples;
  // Keep what later sweeps can still need.
  while (imu_.size() > 2 && imu_[1].stamp_ns < last_stamp_ - 500'000'000) imu_.pop_front();
}

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

Eigen::Isometry3d lidar_motion(const odometry::ImuDelta& inc, const Eigen::Isometry3d& T_lidar_imu, const ImuStart* start) {
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

std::optional<Eigen::Matrix3d> FrontendCore::imu_rotation(int64_t from, int64_t to) const {
  const auto inc = integrate_imu(imu_, from, {to}, gyro_bias_, Eigen::Vector3d::Zero()).front();
  if (!inc) return std::nullopt;
  return lidar_motion(*inc, p_.T_lidar_imu, nullptr).rotation();
}

std::unique_ptr<odometry::ImuPreintegration> FrontendCore::preintegrate(int64_t from, int64_t to, const Eigen::Vector3d& bg,
                                                                        const Eigen::Vector3d& ba) const {
  if (imu_.size() < 2 || imu_.front().stamp_ns > from || imu_.back().stamp_ns < to || to <= from) return nullptr;
  auto pre = std::make_unique<odometry::ImuPreintegration>(bg, ba, p_.window.noise);
  for (size_t i = 0; i + 1 < imu_.size(); ++i) {
    const int64_t a = std::max(imu_[i].stamp_ns, from), b = std::min(imu_[i + 1].stamp_ns, to);
    if (b > a) pre->integrate(imu_[i].gyro, imu_[i].accel, static_cast<double>(b - a) * 1e-9);
  }
  return pre;
}

std::optional<ImuState> FrontendCore::imu_state() const {
  if (!window_ || !window_->ready()) return std::nullopt;
  return window_->latest();
}

std::optional<Eigen::Vector3d> FrontendCore::gravity() const {
  if (!window_ || !window_->gravity_known()) return std::nullopt;
  return window_->gravity();
}

// The window takes each sweep's pose with the registration's information (the same scaled Hessian
// the keyframes' information comes from; a sweep whose registration failed gets a weak one, so the
// IMU carries it), and the IMU since the previous sweep (`pre`, none where it does not cover).
void FrontendCore::update_window(int64_t stamp_ns, const Eigen::Isometry3d& T, const odometry::RegistrationOutput& reg,
                                 std::unique_ptr<odometry::ImuPreintegration> pre) {
  if (!p_.imu_window || imu_.empty()) return;
  if (!window_) window_ = std::make_unique<ImuWindow>(p_.window, p_.T_lidar_imu);
  const Matrix6d info = reg.converged && reg.correspondences > 0 ? Matrix6d(reg.hessian * p_.information_scale)
                                                                 : Matrix6d(Matrix6d::Identity());
  const uint64_t restarts = window_->restarts();
  window_->add(stamp_ns, T, info, std::move(pre));
  stats_.imu_window_restarts += window_->restarts() - restarts;
  gyro_bias_ = window_->ready() ? window_->latest().bg : Eigen::Vector3d::Zero();
}

Eigen::Isometry3d FrontendCore::level(const Eigen::Isometry3d& T) {
  if (first_ || !p_.level_with_gravity) return T;
  if (window_ && window_->ready()) {
    // The window's gravity (map frame) through a linear-trend filter: it follows a steadily
    // drifting tilt without lag and averages the estimate's sweep-to-sweep noise.
    const Eigen::Vector3d g = window_->gravity().normalized();
    if (!gravity_smoothed_) {
      gravity_smoothed_ = g;
      gravity_trend_.setZero();
    }
    const Eigen::Vector3d predicted = *gravity_smoothed_ + gravity_trend_;
    gravity_smoothed_ = (predicted + p_.level_gain * (g - predicted)).normalized();
    gravity_trend_ += p_.level_trend_gain * (g - predicted);
    if (!gravity_reference_) {
      if (++level_sweeps_ >= p_.level_reference_sweeps) gravity_reference_ = *gravity_smoothed_;
    } else {
      level_ = Eigen::Quaterniond::FromTwoVectors(*gravity_smoothed_, *gravity_reference_);
      stats_.level_deg = Eigen::AngleAxisd(level_).angle() * 180.0 / M_PI;
      stats_.max_level_deg = std::max(stats_.max_level_deg, stats_.level_deg);
    }
  }
  // The registered increment, turned into the levelled frame; the orientation turned likewise.
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = level_.toRotationMatrix() * T.linear();
  out.translation() = T_out_last_.translation() + level_ * (T.translation() - T_last_.translation());
  return out;
}

std::vector<Eigen::Vector3d> FrontendCore::prepare(int64_t stamp_ns, const std::vector<ScanPoint>& points,
                                                   const Eigen::Isometry3d& sweep_motion, const ImuStart* start,
                                                   std::vector<uint16_t>& rings) const {
  // Motion over the sweep (0.1 s nominal) sampled at 64 instants; each point is moved into the
  // sensor frame at the sweep's start.
  constexpr int kSlots = 64;
  float t_max = 0;
  for (const auto& pt : points) t_max = std::max(t_max, pt.time_offset);
  const double r2min = p_.min_range_m * p_.min_range_m, r2max = p_.max_range_m * p_.max_range_m;
  std::vector<Eigen::Vector3d> out;
  out.reserve(points.size());
  rings.clear();
  rings.reserve(points.size());
  if (!p_.deskew || !(t_max > 0)) {
    // Not deskewed, or a sweep without per-point times (all zero): taken as it is.
    for (const auto& pt : points) {
      const Eigen::Vector3d p = pt.p.cast<double>();
      const double r2 = p.squaredNorm();
      if (!(r2 >= r2min && r2 <= r2max)) continue;
      rings.push_back(pt.ring);
      out.push_back(p);
    }
    return out;
  }
  const double span = std::max(1e-3, static_cast<double>(t_max));
  std::array<Eigen::Isometry3d, kSlots + 1> slot;
  const Vector6d xi = geometry::se3_log(sweep_motion);  // over `span`
  std::vector<int64_t> instants(kSlots + 1);
  for (int k = 0; k <= kSlots; ++k) {
    const double f = static_cast<double>(k) / kSlots;
    slot[static_cast<size_t>(k)] = geometry::se3_exp(xi * f);
    instants[static_cast<size_t>(k)] = stamp_ns + static_cast<int64_t>(f * span * 1e9);
  }
  if (!imu_.empty()) {
    const Eigen::Vector3d ba = start != nullptr && window_ ? window_->latest().ba : Eigen::Vector3d::Zero();
    const auto inc = integrate_imu(imu_, stamp_ns, instants, gyro_bias_, ba);  // one pass for all slots
    for (size_t k = 0; k < inc.size(); ++k) {
      if (!inc[k]) continue;
      const Eigen::Isometry3d m = lidar_motion(*inc[k], p_.T_lidar_imu, start);
      if (start != nullptr) {
        slot[k] = m;
      } else {
        slot[k].linear() = m.linear();
      }
    }
  }
  for (const auto& pt : points) {
    const Eigen::Vector3d p = pt.p.cast<double>();
    const double r2 = p.squaredNorm();
    if (!(r2 >= r2min && r2 <= r2max)) continue;
    rings.push_back(pt.ring);
    const int k = std::clamp(static_cast<int>(std::lround(pt.time_offset / span * kSlots)), 0, kSlots);
    out.push_back(slot[static_cast<size_t>(k)] * p);
  }
  return out;
}

std::vector<Eigen::Vector3f> FrontendCore::keyframe_cloud(const std::vector<Eigen::Vector3d>& deskewed) const {
  std::vector<Eigen::Vector3f> cloud;
  for (const auto& p : odometry::voxel_filter(deskewed, p_.keyframe_voxel_m)) cloud.push_back(p.cast<float>());
  return cloud;
}

Eigen::Isometry3d FrontendCore::predict(int64_t stamp_ns, double dt, std::unique_ptr<odometry::ImuPreintegration>& pre,
                                        std::optional<ImuStart>& imu_start) {
  Eigen::Isometry3d delta = geometry::se3_exp(geometry::se3_log(delta_) * (dt / dt_last_));
  // The IMU since the previous sweep, at the window's biases: for the prediction and the window.
  if (!first_ && window_) {
    const ImuState st = window_->ready() ? window_->latest() : ImuState{};
    pre = preintegrate(last_stamp_, stamp_ns, st.bg, st.ba);
  }
  if (first_) return delta;
  if (window_ && window_->ready() && pre) {
    // The motion the IMU predicts from the window's latest pose, applied to the registered one.
    const Eigen::Isometry3d d = window_->latest_lidar().inverse() * window_->predict_lidar(*pre);
    const Eigen::Isometry3d gap = delta.inverse() * d;
    if (d.matrix().allFinite() && gap.translation().norm() <= p_.max_imu_prediction_gap_m &&
        angle_of(gap) <= p_.max_imu_prediction_gap_rad) {
      ++stats_.imu_predictions;
      if (p_.imu_deskew) {
        const ImuState next = window_->predict(*pre);
        const Eigen::Matrix3d Rt = next.q.toRotationMatrix().transpose();
        imu_start = ImuStart{Rt * next.v, Rt * window_->gravity()};
      }
      return d;
    }
    ++stats_.imu_predictions_rejected;
  }
  if (const auto R = imu_rotation(last_stamp_, stamp_ns)) delta.linear() = *R;
  return delta;
}

Eigen::Isometry3d FrontendCore::motion_over(const Eigen::Isometry3d& D, float t_max, double dt) {
  return geometry::se3_exp(geometry::se3_log(D) * (static_cast<double>(t_max) / dt));
}

FrontendCore::Sweep FrontendCore::select(int64_t stamp_ns, const std::vector<ScanPoint>& points, const Eigen::Isometry3d& motion,
                                         const ImuStart* start) const {
  Sweep sw;
  std::vector<uint16_t> rings;
  sw.cloud = prepare(stamp_ns, points, motion, start, rings);
  const bool has_rings = std::any_of(rings.begin(), rings.end(), [](uint16_t r) { return r != 0; });
  if (has_rings) {
    const std::vector<size_t> keep = odometry::voxel_filter_indices(sw.cloud, p_.voxel_m);
    const std::vector<Eigen::Vector3d> all_normals = odometry::range_image_normals(sw.cloud, rings, p_.image_columns);
    for (size_t i : keep) {
      if (all_normals[i].squaredNorm() < 0.5) continue;
      sw.points.push_back(sw.cloud[i]);
      sw.normals.push_back(all_normals[i]);
    }
    return sw;
  }
  // No ring structure (a saved KITTI sweep): normals from each point's nearest neighbours, in the
  // sweep reduced to one point per normal_voxel_m voxel (which the rest of the sweep's use takes
  // too): the k-d tree is built on a fraction of a dense sweep's points, and a near point's
  // neighbours spread over several rings instead of lying on its own.
  if (p_.normal_voxel_m > 0) sw.cloud = odometry::voxel_filter(sw.cloud, p_.normal_voxel_m);
  const std::vector<Eigen::Vector3d> sel = odometry::voxel_filter(sw.cloud, p_.voxel_m);
  const std::vector<Eigen::Vector3d> n = odometry::knn_normals(sel, sw.cloud, 10, 1.5);
  for (size_t i = 0; i < sel.size(); ++i) {
    if (n[i].squaredNorm() < 0.5) continue;
    sw.points.push_back(sel[i]);
    sw.normals.push_back(n[i]);
  }
  return sw;
}

odometry::RegistrationParams FrontendCore::adaptive_params() const {
  odometry::RegistrationParams rp = p_.registration;
  if (model_errors_.size() >= 5) {
    const double ms = std::accumulate(model_errors_.begin(), model_errors_.end(), 0.0,
                                      [](double a, double e) { return a + e * e; }) /
                      static_cast<double>(model_errors_.size());
    rp.max_correspondence_m = std::clamp(3.0 * std::sqrt(ms), p_.min_gate_m, p_.max_gate_m);
  } else {
    rp.max_correspondence_m = p_.initial_gate_m;
  }
  // The kernel follows the gate as in KISS-ICP: gate 3 sigma, kernel sigma / 3.
  rp.kernel_m = rp.max_correspondence_m / p_.kernel_divisor;
  return rp;
}

Eigen::Isometry3d FrontendCore::register_sweep(const SweepIn& in, const Eigen::Isometry3d& guess, bool imu_deskewed, Sweep& sweep,
                                               ScanOut& out) {
  const odometry::RegistrationParams rp = adaptive_params();
  Candidate c{odometry::register_to_map(sweep.points, sweep.normals, map_, guess, rp), {}, guess};
  if (!first_points_.empty() && stats_.scans == 2 && c.reg.converged) {
    // The first sweep went into the map undeskewed (its motion was unknown). Now that the motion
    // is known, rebuild the map from both sweeps deskewed, and register this one again.
    const Eigen::Isometry3d D = T_last_.inverse() * c.reg.T_map_sensor;
    float first_t_max = 0;
    for (const auto& pt : first_points_) first_t_max = std::max(first_t_max, pt.time_offset);
    map_ = odometry::VoxelMap(p_.map);
    const Sweep first = select(first_stamp_, first_points_, motion_over(D, first_t_max, in.dt), nullptr);
    if (held_first_keyframe_) held_first_keyframe_->cloud = keyframe_cloud(first.cloud);
    std::vector<Eigen::Vector3d> world = odometry::voxel_filter(first.cloud, p_.map_voxel_m);
    for (auto& p : world) p = T_last_ * p;
    map_.add(world);
    sweep = select(in.stamp_ns, *in.points, motion_over(D, in.t_max, in.dt), nullptr);
    c.reg = odometry::register_to_map(sweep.points, sweep.normals, map_, c.reg.T_map_sensor, rp);
    first_points_.clear();
    first_points_.shrink_to_fit();
  }
  const bool redeskew = p_.deskew && in.t_max > 0 && p_.redeskew && !imu_deskewed;
  if (redeskew && stats_.scans > 2 && c.reg.converged) {
    // Deskew again with the motion just estimated (the prediction's error leaves a residual
    // distortion), and refine. A sweep deskewed with the IMU's whole motion keeps it: the
    // registration corrects the pose, not the velocity the IMU's motion starts from.
    sweep = select(in.stamp_ns, *in.points, motion_over(T_last_.inverse() * c.reg.T_map_sensor, in.t_max, in.dt), nullptr);
    c.reg = odometry::register_to_map(sweep.points, sweep.normals, map_, c.reg.T_map_sensor, rp);
  }
  c.fit = fit_of(sweep, c.reg);
  // Recovery: a registration that failed, slid far from the prediction or fits the map clearly
  // worse than the sweeps before it (the prediction too far off for the gate: a sharp turn, a start
  // after standing still) is tried again from other guesses, and the best fit taken.
  if (p_.recovery.enabled && poor_registration(guess, c)) {
    ++stats_.recovery_attempts;
    if (recover(in, guess, rp, redeskew && stats_.scans > 2, sweep, c)) {
      ++stats_.recoveries;
      out.recovered = true;
    }
  }
  out.registration = c.reg;
  out.fit = c.fit;
  // A registration that lands further from where it started than the widest gate (or turns more
  // than max_jump_rad) has slid into a wrong minimum, not followed the robot: keep the prediction.
  if (out.registration.converged && !plausible_registration(c.start, out.registration.T_map_sensor, p_)) {
    out.registration.converged = false;
    ++stats_.registration_rejected;
  }
  if (!out.registration.converged) {
    ++stats_.registration_failures;
    return guess;
  }
  recent_fits_.push_back(c.fit.inlier_fraction);
  if (recent_fits_.size() > p_.recovery.fit_history) recent_fits_.pop_front();
  const Eigen::Isometry3d dev = guess.inverse() * c.reg.T_map_sensor;
  model_errors_.push_back(dev.translation().norm() + 10.0 * angle_of(dev));
  if (model_errors_.size() > 100) model_errors_.pop_front();
  return c.reg.T_map_sensor;
}

ScanOut FrontendCore::process(int64_t stamp_ns, const std::vector<ScanPoint>& points) {
  ScanOut out;
  out.stamp_ns = stamp_ns;
  ++stats_.scans;
  SweepIn in{stamp_ns, &points, 0.0F, first_ ? 0.1 : std::max(1e-3, static_cast<double>(stamp_ns - last_stamp_) * 1e-9)};
  for (const auto& pt : points) in.t_max = std::max(in.t_max, pt.time_offset);
  // Prediction: the IMU window's latest state propagated with the bias-corrected IMU; until the
  // window runs, constant velocity with the IMU's rotation when it covers the interval.
  std::unique_ptr<odometry::ImuPreintegration> pre;
  std::optional<ImuStart> imu_start;  // the IMU's state at this sweep's start, when predicted
  const Eigen::Isometry3d delta = predict(stamp_ns, in.dt, pre, imu_start);
  // Deskewed with the predicted motion scaled to the sweep's span. A sweep whose points all carry
  // time 0 has no per-point times (motion-compensated, or saved without them): it is taken as it
  // is, with no deskewing and nothing to deskew again.
  const bool deskew = p_.deskew && in.t_max > 0;
  Sweep sweep = select(stamp_ns, points, first_ ? Eigen::Isometry3d::Identity() : motion_over(delta, in.t_max, in.dt),
                       imu_start ? &*imu_start : nullptr);
  out.points_used = sweep.points.size();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  if (!first_) T = map_.empty() ? T_last_ * delta : register_sweep(in, T_last_ * delta, imu_start.has_value(), sweep, out);
  const double dt = in.dt;
  update_window(stamp_ns, T, out.registration, std::move(pre));
  // Map update (points in the odometry frame) and sliding.
  {
    std::vector<Eigen::Vector3d> world = odometry::voxel_filter(sweep.cloud, p_.map_voxel_m);
    for (auto& p : world) p = T * p;
    map_.add(world);
    if (stats_.scans % 10 == 0) map_.remove_far(T.translation());
  }
  const Eigen::Isometry3d T_map = T;
  const Eigen::Isometry3d T_out = level(T_map);
  if (!first_) {
    delta_ = T_last_.inverse() * T_map;
    dt_last_ = dt;
    out.linear_velocity = (T_out.translation() - T_out_last_.translation()) / dt;
    out.angular_velocity = geometry::so3_log(delta_.rotation()) / dt;
  }
  // Keyframes: relative odometry with an information matrix from the registrations in between.
  if (out.registration.correspondences > 0) {
    const Matrix6d info_step = out.registration.hessian * p_.keyframe_information_scale;
    const Eigen::LDLT<Matrix6d> ldlt(info_step);
    if (ldlt.info() == Eigen::Success) cov_since_keyframe_ += ldlt.solve(Matrix6d::Identity());
  }
  const Eigen::Isometry3d since = T_last_keyframe_.inverse() * T_out;
  if (held_first_keyframe_) {
    // The second sweep: the first keyframe goes out now, deskewed if the motion was found (above);
    // this sweep cuts none, the next one is measured from the first.
    out.keyframe = std::move(held_first_keyframe_);
    held_first_keyframe_.reset();
  } else if (!have_keyframe_ || since.translation().norm() >= p_.keyframe_distance_m ||
             angle_of(since) >= p_.keyframe_angle_rad) {
    KeyframeOut k;
    k.id = next_keyframe_++;
    k.stamp_ns = stamp_ns;
    k.T_odom_keyframe = T_out;
    k.T_prev = have_keyframe_ ? since : Eigen::Isometry3d::Identity();
    Matrix6d cov = cov_since_keyframe_;
    cov.diagonal().array() += 1e-8;
    k.information = have_keyframe_ ? Matrix6d(cov.inverse()) : Matrix6d::Identity() * 1e6;
    k.information = 0.5 * (k.information + k.information.transpose());
    k.cloud = keyframe_cloud(sweep.cloud);
    keyframe_poses_.emplace_back(k.id, T_out);
    T_last_keyframe_ = T_out;
    cov_since_keyframe_.setZero();
    have_keyframe_ = true;
    ++stats_.keyframes;
    if (first_ && deskew) {
      held_first_keyframe_ = std::move(k);
    } else {
      out.keyframe = std::move(k);
    }
  }
  // Corrections: the published pose follows the odometry's own increment and is pulled towards
  // the corrected pose by at most the fusion thresholds per scan (eq. 8-14).
  const Eigen::Isometry3d increment = first_ ? Eigen::Isometry3d::Identity() : T_out_last_.inverse() * T_out;
  if (correction_) {
    const geometry::FusionResult f = geometry::fuse_pose(published_ * increment, *correction_ * T_out, p_.fusion);
    published_ = f.fused;
    out.fusion_lambda = f.lambda;
  } else {
    published_ = T_out;
  }
  out.T_odom_raw = T_out;
  out.T_odom_base = published_;
  if (T_world_robot_) out.T_world_base = *T_world_robot_ * published_;
  if (first_ && deskew) {
    first_points_ = points;
    first_stamp_ = stamp_ns;
  }
  // The sweep (sensor frame) for the next one's global registration, with its features if recovery
  // made them.
  prev_cloud_ = std::move(sweep.cloud);
  prev_features_ = std::move(current_features_);
  current_features_.reset();
  T_last_ = T_map;
  T_out_last_ = T_out;
  last_stamp_ = stamp_ns;
  first_ = false;
  return out;
}

odometry::FitQuality FrontendCore::fit_of(const Sweep& sweep, const odometry::RegistrationOutput& reg) const {
  return odometry::evaluate_fit(sweep.points, sweep.normals, map_, reg.T_map_sensor, p_.recovery.fit_distance_m,
                                p_.recovery.fit_inlier_m);
}

double FrontendCore::recent_fit() const {
  if (recent_fits_.size() < p_.recovery.min_history) return 0.0;
  std::vector<double> f(recent_fits_.begin(), recent_fits_.end());
  std::nth_element(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(f.size() / 2), f.end());
  return f[f.size() / 2];
}

bool FrontendCore::poor_registration(const Eigen::Isometry3d& guess, const Candidate& c) const {
  if (!c.reg.converged || !plausible_registration(guess, c.reg.T_map_sensor, p_)) return true;
  return c.fit.inlier_fraction < p_.recovery.poor_fit_ratio * recent_fit();
}

bool FrontendCore::recover(const SweepIn& in, const Eigen::Isometry3d& guess, const odometry::RegistrationParams& rp, bool redeskew,
                           Sweep& sweep, Candidate& c) {
  // The registration from the prediction stays unless a candidate fits clearly better; it competes
  // only if it is one the robot can have made. A candidate that fits as well as the recent sweeps
  // (good_fit_ratio of their median) ends the search.
  const bool have = c.reg.converged && plausible_registration(guess, c.reg.T_map_sensor, p_);
  double best = have ? c.fit.inlier_fraction + p_.recovery.min_gain : -1.0;
  const double median = recent_fit();
  const double good = median > 0 ? p_.recovery.good_fit_ratio * median : 2.0;
  bool replaced = false;
  // One attempt from start s: true when it fits well enough to stop.
  auto attempt = [&](const Eigen::Isometry3d& s) {
    // A deskewed sweep is deskewed with the motion its start implies, and again with the motion found.
    Sweep local;
    const Sweep* sw = &sweep;
    if (redeskew) {
      local = select(in.stamp_ns, *in.points, motion_over(T_last_.inverse() * s, in.t_max, in.dt), nullptr);
      sw = &local;
    }
    // Coarse to fine: the wide gates reach a sweep the prediction left far off, the last one (the
    // adaptive gate) fits it as the registration from the prediction does.
    odometry::RegistrationOutput r;
    r.T_map_sensor = s;
    r.converged = true;
    for (const double gate : p_.recovery.gates_m) {
      if (gate <= rp.max_correspondence_m || !r.converged) break;
      odometry::RegistrationParams coarse = rp;
      coarse.max_correspondence_m = gate;
      coarse.kernel_m = gate / p_.kernel_divisor;
      r = odometry::register_to_map(sw->points, sw->normals, map_, r.T_map_sensor, coarse);
    }
    if (!r.converged) return false;
    r = odometry::register_to_map(sw->points, sw->normals, map_, r.T_map_sensor, rp);
    if (redeskew && r.converged) {
      local = select(in.stamp_ns, *in.points, motion_over(T_last_.inverse() * r.T_map_sensor, in.t_max, in.dt), nullptr);
      r = odometry::register_to_map(local.points, local.normals, map_, r.T_map_sensor, rp);
    }
    if (!r.converged || !plausible_registration(s, r.T_map_sensor, p_)) return false;
    const odometry::FitQuality f = fit_of(*sw, r);
    if (f.inlier_fraction <= best) return false;
    best = f.inlier_fraction;
    c = Candidate{r, f, s};
    if (redeskew) sweep = std::move(local);
    replaced = true;
    return best >= good;
  };
  // From the prediction with wide gates, then from the last pose (no motion).
  if (attempt(guess) || attempt(T_last_)) return true;
  if (!p_.recovery.global || prev_cloud_.empty()) return replaced;
  // The sweep registered globally onto the previous one (features, no guess), put on its pose.
  if (!prev_features_) prev_features_ = odometry::make_feature_cloud(prev_cloud_, p_.recovery.global_params);
  current_features_ = odometry::make_feature_cloud(sweep.cloud, p_.recovery.global_params);
  const odometry::GlobalRegistrationResult g = odometry::register_global(*current_features_, *prev_features_, p_.recovery.global_params);
  if (!g.ok) return replaced;
  const bool before = replaced;
  replaced = false;
  attempt(T_last_ * g.T_target_source);
  if (replaced) ++stats_.recoveries_global;
  return replaced || before;
}

bool FrontendCore::set_correction(uint32_t keyframe_id, const Eigen::Isometry3d& T_world_keyframe,
                                  const Eigen::Isometry3d& T_world_robot) {
  const auto it = std::find_if(keyframe_poses_.begin(), keyframe_poses_.end(),
                               [&](const auto& k) { return k.first == keyframe_id; });
  if (it == keyframe_poses_.end()) return false;
  // The keyframe's corrected pose in the odometry frame, and the map from raw to corrected odometry.
  const Eigen::Isometry3d corrected = T_world_robot.inverse() * T_world_keyframe;
  Eigen::Isometry3d C = corrected * it->second.inverse();
  if (p_.correction_holds_tilt && gravity_reference_) {
    // Levelled: keep the correction's turn about the vertical, and move the keyframe to its
    // corrected position with it (correction_holds_tilt in frontend_core.hpp).
    const Eigen::Quaterniond yaw = geometry::twist_about(Eigen::Quaterniond(C.rotation()), Eigen::Vector3d::UnitZ());
    C.linear() = yaw.toRotationMatrix();
    C.translation() = corrected.translation() - yaw * it->second.translation();
    ++stats_.corrections_levelled;
  }
  correction_ = C;
  T_world_robot_ = T_world_robot;
  ++stats_.corrections;
  return true;
}

bool plausible_registration(const Eigen::Isometry3d& prediction, const Eigen::Isometry3d& registered,
                            const FrontendParams& p) {
  const Eigen::Isometry3d jump = prediction.inverse() * registered;
  return jump.translation().norm() <= p.max_gate_m && angle_of(jump) <= p.max_jump_rad;
}

}  // namespace cdc::frontend
