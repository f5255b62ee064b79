// SE(3)/SO(3) helpers on Eigen types. The one SE(3) type of cdc-slam is Eigen::Isometry3d;
// tangent vectors are ordered (translation, rotation) like the information matrices.
#pragma once

#include <Eigen/Geometry>

namespace cdc::geometry {

using Vector6d = Eigen::Matrix<double, 6, 1>;

// Skew-symmetric matrix: hat(a) * b == a.cross(b).
Eigen::Matrix3d hat(const Eigen::Vector3d& v);

// Rotation by the rotation vector phi (axis * angle [rad]).
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& phi);
// Rotation vector of R, angle in [0, pi].
Eigen::Vector3d so3_log(const Eigen::Matrix3d& R);

// Left Jacobian of SO(3) and its inverse (translation part of the SE(3) exponential).
Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& phi);
Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& phi);

// SE(3) exponential and logarithm; xi = (rho, phi): rho [m] couples with phi [rad].
Eigen::Isometry3d se3_exp(const Vector6d& xi);
Vector6d se3_log(const Eigen::Isometry3d& T);

Eigen::Isometry3d make_pose(const Eigen::Vector3d& t, const Eigen::Quaterniond& q);

// Angle of a rotation [rad], in [0, pi].
double rotation_angle(const Eigen::Matrix3d& R);

// Roll, pitch, yaw [rad] with R = Rz(yaw) * Ry(pitch) * Rx(roll).
Eigen::Vector3d to_rpy(const Eigen::Matrix3d& R);
Eigen::Matrix3d from_rpy(double roll, double pitch, double yaw);

// Spherical linear interpolation along the shortest arc: t=0 gives a, t=1 gives b (same sign as a).
Eigen::Quaterniond slerp(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double t);

// Pose between a (t=0) and b (t=1): slerp for rotation, linear for translation.
Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double t);

// Twist of q about a unit axis (swing-twist decomposition q = swing * twist): the rotation about
// `axis` alone that is closest to q; identity when q turns the axis by 180 deg (no twist defined).
Eigen::Quaterniond twist_about(const Eigen::Quaterniond& q, const Eigen::Vector3d& axis);

// Nearest rotation matrix to M (projects a drifted matrix back onto SO(3)).
Eigen::Matrix3d project_to_so3(const Eigen::Matrix3d& M);

}  // namespace cdc::geometry
