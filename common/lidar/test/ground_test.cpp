// The ground below a sensor: found at the sensor's height above it whatever stands around (walls,
// the vehicle's own points), along a tilted up, and not guessed from too few points.
#include "cdc/lidar/ground.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <cmath>
#include <random>

namespace cdc::lidar {
namespace {

// A street seen from `height` above its ground: ground points out to 60 m, two walls 8 m either side
// up to 12 m, and the vehicle's own roof within 1.5 m.
std::vector<Eigen::Vector3f> street(double height, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> noise(0, 0.02);
  std::vector<Eigen::Vector3f> cloud;
  for (int i = 0; i < 3000; ++i) {
    const double r = 3 + 57 * (u(rng) + 1) / 2, a = M_PI * u(rng);
    cloud.emplace_back(r * std::cos(a), r * std::sin(a), -height + noise(rng));
  }
  for (int i = 0; i < 3000; ++i) {
    cloud.emplace_back(40 * u(rng), i % 2 == 0 ? 8 : -8, -height + 6 + 6 * u(rng));
  }
  for (int i = 0; i < 300; ++i) cloud.emplace_back(1.5 * u(rng), 0.8 * u(rng), -0.3);
  return cloud;
}

TEST(Ground, FoundAtTheSensorsHeightAboveItAmongWalls) {
  for (double height : {1.73, 6.0}) {
    const auto g = ground_height(street(height, 3), Eigen::Vector3d::UnitZ());
    ASSERT_TRUE(g.has_value());
    EXPECT_NEAR(*g, -height, 0.1) << height;
  }
}

TEST(Ground, MeasuredAlongTheGivenUp) {
  // The sensor pitched by 5 deg: in its frame the ground tilts; along the true up it is still level.
  const Eigen::Matrix3f R = Eigen::AngleAxisf(0.0873f, Eigen::Vector3f::UnitY()).toRotationMatrix();
  std::vector<Eigen::Vector3f> tilted;
  for (const auto& p : street(1.73, 4)) tilted.push_back(R.transpose() * p);
  const Eigen::Vector3d up = (R.transpose() * Eigen::Vector3f::UnitZ()).cast<double>();
  const auto g = ground_height(tilted, up);
  ASSERT_TRUE(g.has_value());
  EXPECT_NEAR(*g, -1.73, 0.1);
}

TEST(Ground, NoEstimateFromTooFewPoints) {
  std::vector<Eigen::Vector3f> few(49, Eigen::Vector3f(5, 0, -1.7f));
  EXPECT_FALSE(ground_height(few, Eigen::Vector3d::UnitZ()).has_value());
  few.emplace_back(5, 1, -1.7f);
  EXPECT_TRUE(ground_height(few, Eigen::Vector3d::UnitZ()).has_value());
  // Points of the vehicle itself, all within 2 m, are not ground.
  EXPECT_FALSE(ground_height(std::vector<Eigen::Vector3f>(500, Eigen::Vector3f(1, 0, -0.3f)), Eigen::Vector3d::UnitZ())
                   .has_value());
}

}  // namespace
}  // namespace cdc::lidar
