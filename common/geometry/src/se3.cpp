#include "cdc/geometry/se3.hpp"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace cdc::geometry {

Eigen::Matrix3d hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(),  //
      v.z(), 0, -v.x(),   //
      -v.y(), v.x(), 0;
  return m;
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  if (theta < 1e-10) {
    return Eigen::Matrix3d::Identity() + hat(phi);
  }
  return Eigen::AngleAxisd(theta, phi / theta).toRotationMatrix();
}

Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  double angle = aa.angle();
  Eigen::Vector3d axis = aa.axis();
  if (angle > M_PI) {  // Eigen may return angles in (pi, 2pi)
    angle = 2.0 * M_PI - angle;
    axis = -axis;
  }
  return axis * angle;
}

Eigen::Matrix3d so3_left_jacobian(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (theta < 1e-6) {
    return Eigen::Matrix3d::Identity() + 0.5 * W + W * W / 6.0;
  }
  const double t2 = theta * theta;
  return Eigen::Matrix3d::Identity() + (1.0 - std::cos(theta)) / t2 * W +
         (theta - std::sin(theta)) / (t2 * theta) * W * W;
}

Eigen::Matrix3d so3_left_jacobian_inverse(const Eigen::Vector3d& phi) {
  const double theta = phi.norm();
  const Eigen::Matrix3d W = hat(phi);
  if (theta < 1e-6) {
    return Eigen::Matrix3d::Identity() - 0.5 * W + W * W / 12.0;
  }
  const double t2 = theta * theta;
  const double coeff = 1.0 / t2 - (1.0 + std::cos(theta)) / (2.0 * theta * std::sin(theta));
  return Eigen::Matrix3d::Identity() - 0.5 * W + coeff * W * W;
}

Eigen::Isometry3d se3_exp(const Vector6d& xi) {
  const Eigen::Vector3d rho = xi.head<3>();
  const Eigen::Vector3d phi = xi.tail<3>();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = so3_exp(phi);
  T.translation() = so3_left_jacobian(phi) * rho;
  return T;
}

Vector6d se3_log(const Eigen::Isometry3d& T) {
  const Eigen::Vector3d phi = so3_log(T.rotation());
  Vector6d xi;
  xi.head<3>() = so3_left_jacobian_inverse(phi) * T.translation();
  xi.tail<3>() = phi;
  return xi;
}

Eigen::Isometry3d make_pose(const Eigen::Vector3d& t, const Eigen::Quaterniond& q) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = q.normalized().toRotationMatrix();
  T.translation() = t;
  return T;
}

double rotation_angle(const Eigen::Matrix3d& R) {
  const double c = std::clamp(0.5 * (R.trace() - 1.0), -1.0, 1.0);
  return std::acos(c);
}

Eigen::Vector3d to_rpy(const Eigen::Matrix3d& R) {
  const double pitch = std::asin(std::clamp(-R(2, 0), -1.0, 1.0));
  const double roll = std::atan2(R(2, 1), R(2, 2));
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  return {roll, pitch, yaw};
}

Eigen::Matrix3d from_rpy(double roll, double pitch, double yaw) {
  return (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

Eigen::Quaterniond slerp(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b, double t) {
  Eigen::Quaterniond qa = a.normalized();
  Eigen::Quaterniond qb = b.normalized();
  double d = qa.dot(qb);
  if (d < 0.0) {  // shortest arc
    qb.coeffs() = -qb.coeffs();
    d = -d;
  }
  if (d > 1.0 - 1e-12) {
    Eigen::Quaterniond q;
    q.coeffs() = (1.0 - t) * qa.coeffs() + t * qb.coeffs();
    return q.normalized();
  }
  const double theta = std::acos(std::clamp(d, -1.0, 1.0));
  const double s = std::sin(theta);
  Eigen::Quaterniond q;
  q.coeffs() = (std::sin((1.0 - t) * theta) / s) * qa.coeffs() + (std::sin(t * theta) / s) * qb.coeffs();
  return q.normalized();
}

Eigen::Isometry3d interpolate(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = slerp(Eigen::Quaterniond(a.rotation()), Eigen::Quaterniond(b.rotation()), t).toRotationMatrix();
  T.translation() = (1.0 - t) * a.translation() + t * b.translation();
  return T;
}

Eigen::Quaterniond twist_about(const Eigen::Quaterniond& q, const Eigen::Vector3d& axis) {
  const double along = q.vec().dot(axis);
  const Eigen::Vector4d t(q.w(), along * axis.x(), along * axis.y(), along * axis.z());
  const double n = t.norm();
  if (n < 1e-12) return Eigen::Quaterniond::Identity();
  return Eigen::Quaterniond(t[0] / n, t[1] / n, t[2] / n, t[3] / n);
}

Eigen::Matrix3d project_to_so3(const Eigen::Matrix3d& M) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

}  // namespace cdc::geometry
