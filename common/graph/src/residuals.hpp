// Ceres residuals of the pose graph (internal to cdc_graph). Poses are parameterised as
// t[3] and q[4] (Eigen storage x, y, z, w, on ceres::EigenQuaternionManifold).
#pragma once

#include <ceres/autodiff_manifold.h>
#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Geometry>

namespace cdc::graph::detail {

using Matrix6d = Eigen::Matrix<double, 6, 6>;

// The weighted error of an estimated pose against a measured one:
//   r = sqrt(Omega) [ t_est - t_meas ; 2 vec(q_meas^-1 q_est) ]
// (twice the vector part of the error quaternion: the rotation angle for small errors).
template <typename T>
void weighted_pose_error(const Eigen::Matrix<T, 3, 1>& t_est, const Eigen::Quaternion<T>& q_est,
                         const Eigen::Vector3d& t_meas, const Eigen::Quaterniond& q_meas, const Matrix6d& sqrt_info,
                         T* out) {
  const Eigen::Quaternion<T> dq = q_meas.template cast<T>().conjugate() * q_est;
  Eigen::Map<Eigen::Matrix<T, 6, 1>> r(out);
  r.template head<3>() = t_est - t_meas.template cast<T>();
  r.template tail<3>() = T(2.0) * dq.vec();
  r.applyOnTheLeft(sqrt_info.template cast<T>());
}

// Between factor, full information (the residual of Ceres' pose_graph_3d example):
//   T_ab_est = inv(T_a) T_b,  r = sqrt(Omega) [ t_ab_est - t_ab ; 2 vec(q_ab^-1 q_ab_est) ].
struct BetweenResidual {
  BetweenResidual(const Eigen::Isometry3d& T_a_b, const Matrix6d& sqrt_information)
      : t_ab(T_a_b.translation()), q_ab(T_a_b.rotation()), sqrt_info(sqrt_information) {}

  template <typename T>
  bool operator()(const T* ta, const T* qa, const T* tb, const T* qb, T* out) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> p_a(ta), p_b(tb);
    Eigen::Map<const Eigen::Quaternion<T>> q_a(qa), q_b(qb);
    const Eigen::Quaternion<T> q_a_inv = q_a.conjugate();
    const Eigen::Quaternion<T> q_ab_est = q_a_inv * q_b;
    const Eigen::Matrix<T, 3, 1> p_ab_est = q_a_inv * (p_b - p_a);
    weighted_pose_error(p_ab_est, q_ab_est, t_ab, q_ab, sqrt_info, out);
    return true;
  }

  static ceres::CostFunction* create(const Eigen::Isometry3d& T_a_b, const Matrix6d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<BetweenResidual, 6, 3, 4, 3, 4>(
        new BetweenResidual(T_a_b, sqrt_information));
  }

  Eigen::Vector3d t_ab;
  Eigen::Quaterniond q_ab;
  Matrix6d sqrt_info;
};

// Inter-robot factor seen by a robot that moves rigidly: its pose is C * T_mine (C the rigid
// correction being solved for), the other robot's pose is fixed. mine_is_a tells which end of
// the factor T_a_b is the robot's own.
struct RigidCorrectionResidual {
  RigidCorrectionResidual(const Eigen::Isometry3d& T_mine, const Eigen::Isometry3d& T_other,
                          const Eigen::Isometry3d& T_a_b, const Matrix6d& sqrt_information, bool mine_is_a)
      : mine(T_mine), other(T_other), between(T_a_b, sqrt_information), a_is_mine(mine_is_a) {}

  template <typename T>
  bool operator()(const T* ct, const T* cq, T* out) const {
    Eigen::Map<const Eigen::Matrix<T, 3, 1>> c_t(ct);
    Eigen::Map<const Eigen::Quaternion<T>> c_q(cq);
    const Eigen::Quaternion<T> q_mine = c_q * Eigen::Quaterniond(mine.rotation()).template cast<T>();
    const Eigen::Matrix<T, 3, 1> t_mine = c_q * mine.translation().template cast<T>() + c_t;
    const Eigen::Quaterniond q_other_d(other.rotation());
    const Eigen::Quaternion<T> q_other = q_other_d.template cast<T>();
    const Eigen::Matrix<T, 3, 1> t_other = other.translation().template cast<T>();
    if (a_is_mine) {
      return between(t_mine.data(), q_mine.coeffs().data(), t_other.data(), q_other.coeffs().data(), out);
    }
    return between(t_other.data(), q_other.coeffs().data(), t_mine.data(), q_mine.coeffs().data(), out);
  }

  static ceres::CostFunction* create(const Eigen::Isometry3d& T_mine, const Eigen::Isometry3d& T_other,
                                     const Eigen::Isometry3d& T_a_b, const Matrix6d& sqrt_information, bool mine_is_a) {
    return new ceres::AutoDiffCostFunction<RigidCorrectionResidual, 6, 3, 4>(
        new RigidCorrectionResidual(T_mine, T_other, T_a_b, sqrt_information, mine_is_a));
  }

  Eigen::Isometry3d mine, other;
  BetweenResidual between;
  bool a_is_mine;
};

// Manifold of rotations about z for planar graphs lifted into 3D: x (+) d = x * (0, 0, sin(d/2),
// cos(d/2)) in Eigen's (x, y, z, w) storage.
struct YawOnlyQuaternion {
  template <typename T>
  bool Plus(const T* x, const T* delta, T* out) const {
    Eigen::Map<const Eigen::Quaternion<T>> q(x);
    const Eigen::Quaternion<T> d(cos(delta[0] / T(2)), T(0), T(0), sin(delta[0] / T(2)));
    Eigen::Map<Eigen::Quaternion<T>> result(out);
    result = q * d;
    return true;
  }
  template <typename T>
  bool Minus(const T* y, const T* x, T* out) const {
    Eigen::Map<const Eigen::Quaternion<T>> qy(y), qx(x);
    const Eigen::Quaternion<T> d = qx.conjugate() * qy;
    out[0] = T(2) * atan2(d.z(), d.w());
    return true;
  }
};

// Prior on one pose: r = sqrt(Omega) [ t - t_prior ; 2 vec(q_prior^-1 q) ].
struct PriorResidual {
  PriorResidual(const Eigen::Isometry3d& T_prior, const Matrix6d& sqrt_information)
      : t0(T_prior.translation()), q0(T_prior.rotation()), sqrt_info(sqrt_information) {}

  template <typename T>
  bool operator()(const T* t, const T* q, T* out) const {
    const Eigen::Matrix<T, 3, 1> p(t[0], t[1], t[2]);
    const Eigen::Quaternion<T> qq(q[3], q[0], q[1], q[2]);  // Eigen's storage is x, y, z, w
    weighted_pose_error(p, qq, t0, q0, sqrt_info, out);
    return true;
  }

  static ceres::CostFunction* create(const Eigen::Isometry3d& T_prior, const Matrix6d& sqrt_information) {
    return new ceres::AutoDiffCostFunction<PriorResidual, 6, 3, 4>(new PriorResidual(T_prior, sqrt_information));
  }

  Eigen::Vector3d t0;
  Eigen::Quaterniond q0;
  Matrix6d sqrt_info;
};

}  // namespace cdc::graph::detail
