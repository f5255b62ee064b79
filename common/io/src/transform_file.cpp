#include "cdc/io/transform_file.hpp"

#include <fstream>
#include <string>

namespace cdc::io {

Eigen::Isometry3d read_transform_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw FormatError(path.string() + ": cannot be read");
  Eigen::Matrix4d m;
  for (int i = 0; i < 16; ++i) {
    if (!(in >> m(i / 4, i % 4))) {
      throw FormatError(path.string() + ": expected 16 numbers (a 4x4 matrix, row by row), found " + std::to_string(i));
    }
  }
  if (std::string rest; in >> rest) throw FormatError(path.string() + ": more than 16 numbers");
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-3 || R.determinant() < 0 ||
      (m.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).norm() > 1e-9) {
    throw FormatError(path.string() + ": not a rigid transform (rotation not orthonormal or last row not 0 0 0 1)");
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

}  // namespace cdc::io
