// Saved clouds and reference transforms: KITTI .bin, PCD and PLY read by their fields' names, and
// a file that is not what it claims is named in the error.
#include "cdc/geometry/se3.hpp"
#include "cdc/io/cloud.hpp"
#include "cdc/io/transform_file.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <unistd.h>

namespace cdc::io {
namespace {

class CloudFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() / ("cdc-cloud-files-" + std::to_string(::getpid()));
    std::filesystem::create_directories(dir_);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& header, const std::vector<float>& values) {
    const std::string path = (dir_ / name).string();
    std::ofstream out(path, std::ios::binary);
    out << header;
    out.write(reinterpret_cast<const char*>(values.data()),
              static_cast<std::streamsize>(values.size() * sizeof(float)));
    return path;
  }
  std::string error_of(const std::string& path) {
    try {
      read_cloud_xyz(path);
    } catch (const FormatError& e) {
      return e.what();
    }
    return "";
  }
  std::filesystem::path dir_;
};

TEST_F(CloudFiles, ReadsKittiPcdAndPlyAndNamesWhatIsWrong) {
  const std::vector<float> two = {1, 2, 3, 9, 4, 5, 6, 9};  // x y z i, twice
  const auto bin = read_cloud_xyz(write("a.bin", "", two));
  ASSERT_EQ(bin.size(), 2u);
  EXPECT_EQ(bin[1], Eigen::Vector3d(4, 5, 6));
  // PCD with intensity first: x, y, z found by name.
  const auto pcd = read_cloud_xyz(
      write("a.pcd",
            "VERSION 0.7\nFIELDS intensity x y z\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\n"
            "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA binary\n",
            {9, 1, 2, 3, 9, 4, 5, 6}));
  ASSERT_EQ(pcd.size(), 2u);
  EXPECT_EQ(pcd[0], Eigen::Vector3d(1, 2, 3));
  const auto ply = read_cloud_xyz(write(
      "a.ply",
      "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\n"
      "property float scalar_intensity\nend_header\n",
      two));
  ASSERT_EQ(ply.size(), 2u);
  EXPECT_EQ(ply[1], Eigen::Vector3d(4, 5, 6));
  for (const std::string& bad :
       {write("b.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 5\nDATA binary\n", {1, 2, 3}),
        write("d.pcd", "FIELDS x y\nSIZE 4 4\nTYPE F F\nPOINTS 1\nDATA binary\n", {1, 2}),
        write("b.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n", {})}) {
    EXPECT_NE(error_of(bad).find(bad), std::string::npos) << bad << ": " << error_of(bad);
  }
  EXPECT_NE(error_of(write("c.bin", "", {1, 2, 3})).find("multiple of 16"), std::string::npos);
  EXPECT_NE(error_of(write("a.xyz", "", {})).find("not a .bin, .pcd or .ply"), std::string::npos);
  EXPECT_NE(error_of((dir_ / "missing.pcd").string()).find("cannot open"), std::string::npos);
}

TEST_F(CloudFiles, TransformFilesMustHoldARigidTransform) {
  const std::string good = (dir_ / "T.txt").string();
  std::ofstream(good) << "0 -1 0 1\n1 0 0 2\n0 0 1 3\n0 0 0 1\n";
  const Eigen::Isometry3d T = read_transform_file(good);
  EXPECT_NEAR((T.translation() - Eigen::Vector3d(1, 2, 3)).norm(), 0, 1e-12);
  EXPECT_NEAR(geometry::rotation_angle(T.rotation()), M_PI / 2, 1e-9);
  const std::string scaled = (dir_ / "S.txt").string();
  std::ofstream(scaled) << "2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n";
  EXPECT_THROW(read_transform_file(scaled), FormatError);
  const std::string short_file = (dir_ / "short.txt").string();
  std::ofstream(short_file) << "1 0 0 0\n0 1 0 0\n";
  EXPECT_THROW(read_transform_file(short_file), FormatError);
  EXPECT_THROW(read_transform_file(dir_ / "missing.txt"), FormatError);
}

}  // namespace
}  // namespace cdc::io
