#include "cdc/frontend/frontend_core.hpp"

#include "cdc/geometry/se3.hpp"

#include <algorithm>

namespace cdc::frontend {

FrontendCore::FrontendCore(const FrontendParams& params)
    : p_(params),
      map_(params.map),
      predictor_(params),
      deskewer_(params),
      gate_(params),
      registration_(params),
      leveller_(params),
      keyframes_(params),
      fusion_(params) {}

void FrontendCore::add_imu(const ImuIn& s) {
  if (imu_.add(s, last_stamp_)) ++stats_.imu_samples;
}

ScanOut FrontendCore::process(int64_t stamp_ns, const std::vector<ScanPoint>& points) {
  ScanOut out;
  out.stamp_ns = stamp_ns;
  ++stats_.scans;
  const SweepIn in = sweep_in(stamp_ns, points);
  Prediction prediction = first_ ? Prediction{} : predictor_.predict(last_stamp_, stamp_ns, in.dt, imu_, stats_);
  Sweep sweep = deskew(in, prediction.delta, prediction.imu_start ? &*prediction.imu_start : nullptr);
  out.points_used = sweep.points.size();
  const Eigen::Isometry3d T_map = locate(in, prediction, sweep, out);
  predictor_.update_window(stamp_ns, T_map, out.registration, std::move(prediction.pre), imu_, stats_);
  add_to_map(sweep.cloud, T_map);
  if (stats_.scans % 10 == 0) map_.remove_far(T_map.translation());
  const Eigen::Isometry3d T_out =
      first_ ? T_map : leveller_.level(T_map, T_last_, T_out_last_, predictor_.running_gravity());
  stats_.level_deg = leveller_.angle_deg();
  stats_.max_level_deg = leveller_.max_angle_deg();
  measure_motion(in.dt, T_map, T_out, out);
  keyframes_.add_registration(out.registration);
  // A deskewed first sweep's keyframe waits for the second sweep, which tells its motion.
  out.keyframe = keyframes_.select(stamp_ns, T_odom_start_ * T_out, sweep.cloud, first_ && p_.deskew && in.t_max > 0);
  stats_.keyframes = keyframes_.count();
  fuse(T_out, out);
  end_sweep(in, T_map, T_out, std::move(sweep));
  return out;
}

SweepIn FrontendCore::sweep_in(int64_t stamp_ns, const std::vector<ScanPoint>& points) const {
  const double dt = first_ ? 0.1 : std::max(1e-3, static_cast<double>(stamp_ns - last_stamp_) * 1e-9);
  return SweepIn{stamp_ns, &points, latest_point_time(points), dt};
}

Sweep FrontendCore::deskew(const SweepIn& in, const Eigen::Isometry3d& motion, const ImuStart* start) const {
  // The first sweep's motion is unknown: it is taken as it is until the second one tells it.
  const Eigen::Isometry3d over_sweep =
      first_ ? Eigen::Isometry3d::Identity() : Deskewer::motion_over(motion, in.t_max, in.dt);
  return deskewer_.prepare(in.stamp_ns, *in.points, over_sweep, predictor_.deskew_imu(imu_, start));
}

Eigen::Isometry3d FrontendCore::locate(const SweepIn& in, const Prediction& prediction, Sweep& sweep, ScanOut& out) {
  if (first_) return Eigen::Isometry3d::Identity();
  const Eigen::Isometry3d guess = T_last_ * prediction.delta;
  if (map_.empty()) return guess;
  // A sweep deskewed with the IMU's whole motion keeps it: the registration corrects the pose, not
  // the velocity the IMU's motion starts from. A sweep without per-point times has nothing to
  // deskew again.
  const bool redeskew = p_.deskew && in.t_max > 0 && p_.redeskew && !prediction.imu_start && stats_.scans > 2;
  RegistrationContext ctx{map_, gate_.params(), T_last_, {}};
  if (redeskew) ctx.redeskew = [&](const Eigen::Isometry3d& T) { return deskew(in, T_last_.inverse() * T, nullptr); };
  Candidate c = registration_.register_from(sweep, ctx, guess);
  if (!first_points_.empty() && stats_.scans == 2 && c.reg.converged) complete_first_sweep(in, ctx, sweep, c);
  const ScanToMapRegistration::Result r = registration_.complete(guess, ctx, sweep, c, stats_);
  out.registration = r.reg;
  out.fit = r.fit;
  out.recovered = r.recovered;
  if (!r.reg.converged) return guess;
  gate_.record(guess, r.reg.T_target_source);
  return r.reg.T_target_source;
}

void FrontendCore::complete_first_sweep(const SweepIn& in, const RegistrationContext& ctx, Sweep& sweep, Candidate& c) {
  const Eigen::Isometry3d D = T_last_.inverse() * c.reg.T_target_source;
  map_ = odometry::VoxelMap(p_.map);
  const DeskewImu imu = predictor_.deskew_imu(imu_, nullptr);
  const Sweep first = deskewer_.prepare(first_stamp_, first_points_,
                                        Deskewer::motion_over(D, latest_point_time(first_points_), in.dt), imu);
  keyframes_.redeskew_held(first.cloud);
  add_to_map(first.cloud, T_last_);
  sweep = deskewer_.prepare(in.stamp_ns, *in.points, Deskewer::motion_over(D, in.t_max, in.dt), imu);
  c.reg = registration_.register_from(sweep, ctx, c.reg.T_target_source).reg;
  first_points_.clear();
  first_points_.shrink_to_fit();
}

void FrontendCore::add_to_map(const std::vector<Eigen::Vector3d>& cloud, const Eigen::Isometry3d& T) {
  std::vector<Eigen::Vector3d> world = odometry::voxel_filter(cloud, p_.map_voxel_m);
  for (auto& p : world) p = T * p;
  map_.add(world);
}

void FrontendCore::measure_motion(double dt, const Eigen::Isometry3d& T_map, const Eigen::Isometry3d& T_out,
                                  ScanOut& out) {
  if (first_) return;
  const Eigen::Isometry3d delta = T_last_.inverse() * T_map;
  predictor_.record_motion(delta, dt);
  out.linear_velocity = T_odom_start_.linear() * (T_out.translation() - T_out_last_.translation()) / dt;
  out.angular_velocity = geometry::so3_log(delta.rotation()) / dt;
}

void FrontendCore::fuse(const Eigen::Isometry3d& T_out, ScanOut& out) {
  const Eigen::Isometry3d increment = first_ ? Eigen::Isometry3d::Identity() : T_out_last_.inverse() * T_out;
  const Eigen::Isometry3d T_odom = T_odom_start_ * T_out;
  const CorrectionFusion::Fused f = fusion_.fuse(increment, T_odom);
  out.T_odom_raw = T_odom;
  out.T_odom_base = f.T_odom_base;
  out.T_world_base = f.T_world_base;
  out.fusion_lambda = f.lambda;
}

void FrontendCore::end_sweep(const SweepIn& in, const Eigen::Isometry3d& T_map, const Eigen::Isometry3d& T_out,
                             Sweep sweep) {
  if (first_ && p_.deskew && in.t_max > 0) {
    first_points_ = *in.points;
    first_stamp_ = in.stamp_ns;
  }
  registration_.recovery().remember_sweep(std::move(sweep.cloud));
  T_last_ = T_map;
  T_out_last_ = T_out;
  last_stamp_ = in.stamp_ns;
  first_ = false;
}

void FrontendCore::continue_sequence(uint32_t newest_id, const Eigen::Isometry3d& T_odom_newest) {
  T_odom_start_ = T_odom_newest;
  Eigen::Matrix<double, 6, 1> sigma;
  sigma << Eigen::Vector3d::Constant(p_.restart_link_sigma_m), Eigen::Vector3d::Constant(p_.restart_link_sigma_rad);
  keyframes_.continue_after(newest_id, T_odom_newest, Matrix6d(sigma.array().square().inverse().matrix().asDiagonal()));
}

bool FrontendCore::set_correction(uint32_t keyframe_id, const Eigen::Isometry3d& T_world_keyframe,
                                  const Eigen::Isometry3d& T_world_robot) {
  const std::optional<Eigen::Isometry3d> T_odom_keyframe = keyframes_.pose_of(keyframe_id);
  if (!T_odom_keyframe) return false;
  if (fusion_.set_correction(*T_odom_keyframe, T_world_keyframe, T_world_robot, leveller_.reference_known())) {
    ++stats_.corrections_levelled;
  }
  ++stats_.corrections;
  return true;
}

}  // namespace cdc::frontend
