#include "cdc/frontend/imu_window.hpp"

#include "cdc/geometry/se3.hpp"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/QR>

#include <algorithm>
#include <cmath>

namespace cdc::frontend {
namespace {

template <class T>
using Vec3 = Eigen::Matrix<T, 3, 1>;
template <class T>
using Quat = Eigen::Quaternion<T>;

// 2 vec(q), q on the positive hemisphere: the rotation vector to first order.
template <class T>
Vec3<T> small_angle(const Quat<T>& q) {
  return q.w() < T(0) ? Vec3<T>(T(-2) * q.vec()) : Vec3<T>(T(2) * q.vec());
}

// LiDAR odometry factor: the IMU state's LiDAR pose against the registered one, in the
// registration's (t, r) right-perturbation coordinates.
struct LidarPoseFactor {
  Eigen::Quaterniond q_meas;
  Eigen::Vector3d t_meas;
  Eigen::Matrix<double, 6, 6> sqrt_info;
  Eigen::Quaterniond q_il;  // IMU <- LiDAR
  Eigen::Vector3d t_il;
  template <class T>
  bool operator()(const T* q, const T* p, T* r) const {
    const Eigen::Map<const Quat<T>> qi(q);
    const Eigen::Map<const Vec3<T>> pi(p);
    const Quat<T> ql = qi * q_il.cast<T>();
    const Vec3<T> pl = qi * t_il.cast<T>() + pi;
    const Quat<T> qm_inv = q_meas.conjugate().cast<T>();
    Eigen::Matrix<T, 6, 1> e;
    e.template head<3>() = qm_inv * (pl - t_meas.cast<T>());
    e.template tail<3>() = small_angle<T>(qm_inv * ql);
    Eigen::Map<Eigen::Matrix<T, 6, 1>> out(r);
    out = sqrt_info.cast<T>() * e;
    return true;
  }
};

// IMU preintegration factor (Forster et al.): rotation, velocity and position residuals of the
// increments corrected to first order for the bias change, whitened by the preintegration's
// covariance; then the bias random walk between the two states.
struct ImuFactor {
  Eigen::Matrix<double, 9, 9> sqrt_info;
  double bg_weight, ba_weight, dt;
  Eigen::Matrix3d JR_bg, Jv_bg, Jv_ba, Jp_bg, Jp_ba;
  Eigen::Quaterniond dR0;
  Eigen::Vector3d dv0, dp0, bg0, ba0;

  ImuFactor(const odometry::ImuPreintegration& p, const odometry::ImuNoiseParams& n) {
    const Eigen::Matrix<double, 9, 9> cov = p.covariance() + Eigen::Matrix<double, 9, 9>::Identity() * 1e-12;
    sqrt_info = Eigen::LLT<Eigen::Matrix<double, 9, 9>>(cov.inverse()).matrixU();
    dt = p.dt();
    bg_weight = 1.0 / (n.gyro_bias_walk * std::sqrt(std::max(dt, 1e-3)));
    ba_weight = 1.0 / (n.accel_bias_walk * std::sqrt(std::max(dt, 1e-3)));
    bg0 = p.gyro_bias();
    ba0 = p.accel_bias();
    dR0 = Eigen::Quaterniond(p.delta_R(bg0));
    dv0 = p.delta_v(bg0, ba0);
    dp0 = p.delta_p(bg0, ba0);
    JR_bg = p.dR_dbg();
    Jv_bg = p.dv_dbg();
    Jv_ba = p.dv_dba();
    Jp_bg = p.dp_dbg();
    Jp_ba = p.dp_dba();
  }

  template <class T>
  bool operator()(const T* qi_, const T* pi_, const T* vi_, const T* bi_, const T* qj_, const T* pj_, const T* vj_,
                  const T* bj_, const T* g_, T* r) const {
    const Eigen::Map<const Quat<T>> qi(qi_), qj(qj_);
    const Eigen::Map<const Vec3<T>> pi(pi_), vi(vi_), pj(pj_), vj(vj_);
    const Vec3<T> dbg = Vec3<T>(bi_[0], bi_[1], bi_[2]) - bg0.cast<T>();
    const Vec3<T> dba = Vec3<T>(bi_[3], bi_[4], bi_[5]) - ba0.cast<T>();
    const Vec3<T> phi = JR_bg.cast<T>() * dbg;
    T cq[4];
    ceres::AngleAxisToQuaternion(phi.data(), cq);  // w, x, y, z
    const Quat<T> dR = dR0.cast<T>() * Quat<T>(cq[0], cq[1], cq[2], cq[3]);
    const Vec3<T> dv = dv0.cast<T>() + Jv_bg.cast<T>() * dbg + Jv_ba.cast<T>() * dba;
    const Vec3<T> dp = dp0.cast<T>() + Jp_bg.cast<T>() * dbg + Jp_ba.cast<T>() * dba;
    const T Dt(dt);
    const Eigen::Map<const Vec3<T>> G(g_);
    const Quat<T> qi_inv = qi.conjugate();
    Eigen::Matrix<T, 9, 1> e;
    e.template segment<3>(0) = small_angle<T>(dR.conjugate() * (qi_inv * qj));
    e.template segment<3>(3) = qi_inv * (vj - vi - G * Dt) - dv;
    e.template segment<3>(6) = qi_inv * (pj - pi - vi * Dt - T(0.5) * G * Dt * Dt) - dp;
    Eigen::Map<Eigen::Matrix<T, 9, 1>> out(r);
    out = sqrt_info.cast<T>() * e;
    for (int k = 0; k < 3; ++k) {
      r[9 + k] = T(bg_weight) * (bj_[k] - bi_[k]);
      r[12 + k] = T(ba_weight) * (bj_[3 + k] - bi_[3 + k]);
    }
    return true;
  }
};

// A diagonal Gaussian prior on an N-vector.
template <int N>
struct VectorPrior {
  Eigen::Matrix<double, N, 1> mean, weight;  // weight = 1 / sigma
  template <class T>
  bool operator()(const T* x, T* r) const {
    for (int k = 0; k < N; ++k) r[k] = T(weight[k]) * (x[k] - T(mean[k]));
    return true;
  }
};

}  // namespace

ImuWindow::ImuWindow(const ImuWindowParams& params, const Eigen::Isometry3d& T_lidar_imu)
    : p_(params), T_lidar_imu_(T_lidar_imu), T_imu_lidar_(T_lidar_imu.inverse()) {}

ImuWindow::~ImuWindow() = default;

Eigen::Isometry3d ImuWindow::latest_lidar() const {
  const ImuState& s = latest();
  return geometry::make_pose(s.p, s.q) * T_imu_lidar_;
}

ImuState ImuWindow::predict(const odometry::ImuPreintegration& pre) const {
  const ImuState& s = latest();
  ImuState out = s;
  Eigen::Matrix3d R;
  pre.predict(s.q.toRotationMatrix(), s.v, s.p, g_, R, out.v, out.p);
  out.q = Eigen::Quaterniond(R).normalized();
  out.stamp_ns = s.stamp_ns + static_cast<int64_t>(std::llround(pre.dt() * 1e9));
  return out;
}

Eigen::Isometry3d ImuWindow::predict_lidar(const odometry::ImuPreintegration& pre) const {
  const ImuState s = predict(pre);
  return geometry::make_pose(s.p, s.q) * T_imu_lidar_;
}

void ImuWindow::start_over() {
  ++restarts_;
  states_.clear();
  alignment_.clear();
  solved_ = false;
}

void ImuWindow::restart() {
  Node last = std::move(states_.back());
  last.preint.reset();
  start_over();
  states_.push_back(std::move(last));
}

void ImuWindow::add(int64_t stamp_ns, const Eigen::Isometry3d& T_odom_lidar, const Matrix6d& information,
                    std::unique_ptr<odometry::ImuPreintegration> since_previous) {
  if (!T_odom_lidar.matrix().allFinite() || !information.allFinite()) {
    start_over();
    return;
  }
  Node n;
  n.state.stamp_ns = stamp_ns;
  const Eigen::Isometry3d T_odom_imu = T_odom_lidar * T_lidar_imu_;
  n.state.q = Eigen::Quaterniond(T_odom_imu.rotation()).normalized();
  n.state.p = T_odom_imu.translation();
  n.T_odom_lidar = T_odom_lidar;
  const Matrix6d info = 0.5 * (information + information.transpose()) + Matrix6d::Identity() * 1e-6;
  const Eigen::LLT<Matrix6d> llt(info);
  n.sqrt_information = llt.info() == Eigen::Success ? Matrix6d(llt.matrixU()) : Matrix6d(Matrix6d::Identity());
  if (!states_.empty() && since_previous && since_previous->dt() > 0) {
    const Node& prev = states_.back();
    n.state.bg = prev.state.bg;
    n.state.ba = prev.state.ba;
    if (solved_) {
      // The IMU's own prediction is the best first guess of the new state's velocity.
      Eigen::Matrix3d R;
      Eigen::Vector3d v, p;
      since_previous->predict(prev.state.q.toRotationMatrix(), prev.state.v, prev.state.p, g_, R, v, p);
      n.state.v = v;
    } else {
      n.state.v = (n.state.p - prev.state.p) / since_previous->dt();
    }
    if (!gravity_known_) {
      alignment_.push_back({prev.state.q.toRotationMatrix(), prev.state.p, n.state.p,
                            since_previous->delta_v(n.state.bg, n.state.ba),
                            since_previous->delta_p(n.state.bg, n.state.ba), since_previous->dt()});
    }
    n.preint = std::move(since_previous);
  } else if (!states_.empty()) {
    start_over();  // the IMU did not cover the interval: start again from this sweep
  }
  states_.push_back(std::move(n));
  while (states_.size() > p_.size) {
    states_.pop_front();
    states_.front().preint.reset();
  }
  if (!gravity_known_) {
    // Two intervals at least: with one, the velocities and gravity are not determined.
    if (alignment_.size() + 1 < std::max<size_t>(p_.align_sweeps, 3) || !align_gravity()) return;
  }
  if (states_.size() >= 2) optimise();
}

// Gravity and the velocities by linear least squares over the intervals kept, from the LiDAR
// poses and the preintegrated increments at the initial bias guess (zero):
//   v_k - v_{k-1} - g dt = R_{k-1} dv,   v_{k-1} dt + g dt^2 / 2 = p_k - p_{k-1} - R_{k-1} dp.
bool ImuWindow::align_gravity() {
  const int m = static_cast<int>(alignment_.size());  // intervals; m + 1 velocities
  const int gcol = 3 * (m + 1);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(6 * m, gcol + 3);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(6 * m);
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  for (int k = 1; k <= m; ++k) {
    const Interval& iv = alignment_[static_cast<size_t>(k - 1)];
    const int row = 6 * (k - 1);
    A.block<3, 3>(row, 3 * k) = I;
    A.block<3, 3>(row, 3 * (k - 1)) = -I;
    A.block<3, 3>(row, gcol) = -I * iv.dt;
    b.segment<3>(row) = iv.R_from * iv.dv;
    // Position rows divided by dt, so both kinds are in m/s.
    A.block<3, 3>(row + 3, 3 * (k - 1)) = I;
    A.block<3, 3>(row + 3, gcol) = I * 0.5 * iv.dt;
    b.segment<3>(row + 3) = (iv.p_to - iv.p_from - iv.R_from * iv.dp) / iv.dt;
  }
  const Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  const Eigen::Vector3d g = x.tail<3>();
  if (!x.allFinite() || std::abs(g.norm() - p_.gravity) > p_.max_gravity_error) {
    // Not a plausible gravity (a bad sweep, a jolt): slide on and try again with the next sweep.
    alignment_.erase(alignment_.begin());
    return false;
  }
  g_ = g.normalized() * p_.gravity;
  // The window's states are the last ones aligned (after a failed alignment dropped its oldest
  // interval, the window can reach further back than the intervals: those states keep their guess).
  const int n = static_cast<int>(states_.size());
  for (int k = 0; k < n; ++k) {
    const int aligned = m + 1 - n + k;
    if (aligned >= 0) states_[static_cast<size_t>(k)].state.v = x.segment<3>(3 * aligned);
  }
  gravity_known_ = true;
  alignment_.clear();
  alignment_.shrink_to_fit();
  return true;
}

// One solve of the window: the states and their LiDAR factors, the IMU factors between them,
// gravity, the anchor; a solution that leaves physics behind restarts the window instead.
void ImuWindow::optimise() {
  ceres::Problem::Options po;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  ceres::EigenQuaternionManifold quaternion;
  ceres::SphereManifold<3> sphere;
  add_states(problem, &quaternion);
  add_imu_factors(problem);
  add_gravity(problem, &sphere);
  add_anchor(problem);
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.max_num_iterations = p_.max_iterations;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  ++solves_;
  if (!summary.IsSolutionUsable() || !plausible_solution()) {
    restart();
    return;
  }
  take_solution();
}

// Each state's parameter blocks (from its estimate) and its LiDAR odometry factor.
void ImuWindow::add_states(ceres::Problem& problem, ceres::Manifold* quaternion) {
  const Eigen::Quaterniond q_il(T_imu_lidar_.rotation());
  const Eigen::Vector3d t_il = T_imu_lidar_.translation();
  for (Node& n : states_) {
    std::copy(n.state.q.coeffs().data(), n.state.q.coeffs().data() + 4, n.qbuf);
    std::copy(n.state.p.data(), n.state.p.data() + 3, n.pbuf);
    std::copy(n.state.v.data(), n.state.v.data() + 3, n.vbuf);
    std::copy(n.state.bg.data(), n.state.bg.data() + 3, n.bbuf);
    std::copy(n.state.ba.data(), n.state.ba.data() + 3, n.bbuf + 3);
    problem.AddParameterBlock(n.qbuf, 4, quaternion);
    problem.AddParameterBlock(n.pbuf, 3);
    problem.AddParameterBlock(n.vbuf, 3);
    problem.AddParameterBlock(n.bbuf, 6);
    auto* lf = new LidarPoseFactor{Eigen::Quaterniond(n.T_odom_lidar.rotation()), n.T_odom_lidar.translation(),
                                   n.sqrt_information, q_il, t_il};
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<LidarPoseFactor, 6, 4, 3>(lf), nullptr, n.qbuf, n.pbuf);
  }
}

void ImuWindow::add_imu_factors(ceres::Problem& problem) {
  for (size_t k = 1; k < states_.size(); ++k) {
    Node& a = states_[k - 1];
    Node& b = states_[k];
    auto* f = new ImuFactor(*b.preint, p_.noise);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<ImuFactor, 15, 4, 3, 3, 6, 4, 3, 3, 6, 3>(f), nullptr,
                             a.qbuf, a.pbuf, a.vbuf, a.bbuf, b.qbuf, b.pbuf, b.vbuf, b.bbuf, gbuf);
  }
}

// Gravity: its direction refined in every window (its norm held) and drawn to its last estimate,
// so the evidence of all windows accumulates; held outright when refinement is off.
void ImuWindow::add_gravity(ceres::Problem& problem, ceres::Manifold* sphere) {
  std::copy(g_.data(), g_.data() + 3, gbuf);
  if (states_.size() <= 1) return;
  if (!p_.refine_gravity) {
    problem.SetParameterBlockConstant(gbuf);
    return;
  }
  problem.SetManifold(gbuf, sphere);
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<VectorPrior<3>, 3, 3>(
                               new VectorPrior<3>{g_, Eigen::Vector3d::Constant(1.0 / p_.gravity_prior_sigma)}),
                           nullptr, gbuf);
}

// The anchor: the oldest state's pose held, its velocity and biases at their last estimate, and
// the biases near zero at a MEMS IMU's scale.
void ImuWindow::add_anchor(ceres::Problem& problem) {
  Node& first = states_.front();
  using P3 = VectorPrior<3>;
  using P6 = VectorPrior<6>;
  P6 zero{Eigen::Matrix<double, 6, 1>::Zero(), Eigen::Matrix<double, 6, 1>::Zero()};
  zero.weight << Eigen::Vector3d::Constant(1.0 / p_.gyro_bias_sigma),
      Eigen::Vector3d::Constant(1.0 / p_.accel_bias_sigma);
  problem.AddResidualBlock(new ceres::AutoDiffCostFunction<P6, 6, 6>(new P6(zero)), nullptr, first.bbuf);
  if (solved_) {
    P6 last{Eigen::Matrix<double, 6, 1>::Zero(), Eigen::Matrix<double, 6, 1>::Zero()};
    last.mean << first.state.bg, first.state.ba;
    last.weight << Eigen::Vector3d::Constant(1.0 / p_.anchor_gyro_bias_sigma),
        Eigen::Vector3d::Constant(1.0 / p_.anchor_accel_bias_sigma);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<P6, 6, 6>(new P6(last)), nullptr, first.bbuf);
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<P3, 3, 3>(
                                 new P3{first.state.v, Eigen::Vector3d::Constant(1.0 / p_.anchor_velocity_sigma)}),
                             nullptr, first.vbuf);
  }
  problem.SetParameterBlockConstant(first.qbuf);
  problem.SetParameterBlockConstant(first.pbuf);
}

// A solution within physics: finite, biases within their limits, each velocity near the LiDAR's.
bool ImuWindow::plausible_solution() const {
  for (size_t k = 0; k < states_.size(); ++k) {
    const Node& n = states_[k];
    const Eigen::Map<const Eigen::Vector3d> v(n.vbuf), bg(n.bbuf), ba(n.bbuf + 3);
    const bool finite = Eigen::Map<const Eigen::Vector4d>(n.qbuf).allFinite() &&
                        Eigen::Map<const Eigen::Vector3d>(n.pbuf).allFinite() && v.allFinite() && bg.allFinite() &&
                        ba.allFinite();
    if (!finite || bg.norm() > p_.max_gyro_bias || ba.norm() > p_.max_accel_bias) return false;
    if (k > 0) {
      const Node& a = states_[k - 1];
      const Eigen::Vector3d v_lidar = (n.state.p - a.state.p) / std::max(n.preint->dt(), 1e-3);
      if ((v - v_lidar).norm() > 2.0 + 0.5 * v_lidar.norm()) return false;
    }
  }
  return true;
}

void ImuWindow::take_solution() {
  if (states_.size() > 1 && p_.refine_gravity)
    g_ = Eigen::Vector3d(gbuf[0], gbuf[1], gbuf[2]).normalized() * p_.gravity;
  for (Node& n : states_) {
    n.state.q = Eigen::Quaterniond(n.qbuf[3], n.qbuf[0], n.qbuf[1], n.qbuf[2]).normalized();
    n.state.p = Eigen::Vector3d(n.pbuf[0], n.pbuf[1], n.pbuf[2]);
    n.state.v = Eigen::Vector3d(n.vbuf[0], n.vbuf[1], n.vbuf[2]);
    n.state.bg = Eigen::Vector3d(n.bbuf[0], n.bbuf[1], n.bbuf[2]);
    n.state.ba = Eigen::Vector3d(n.bbuf[3], n.bbuf[4], n.bbuf[5]);
  }
  solved_ = true;
}

}  // namespace cdc::frontend
