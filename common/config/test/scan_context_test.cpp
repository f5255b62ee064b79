#include "cdc/config/scan_context.hpp"
#include "temp_dir.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fstream>
#include <string>

namespace cdc::config {
namespace {

using ::testing::HasSubstr;

class ScanContextKeys : public test::TempDirTest {
 protected:
  ScanContextKeys() : TempDirTest("scan_context_keys") {}
  // A YAML file in the test's folder holding `text`.
  std::string yaml(const std::string& text) const {
    std::ofstream(path("service.yaml")) << text;
    return path("service.yaml");
  }
};

TEST_F(ScanContextKeys, ReadTheGridAndLeaveTheSensorHeight) {
  Reader r(yaml("scan_context:\n  rings: 10\n  sectors: 30\n  max_range_m: 50\n"));
  lidar::ScanContextParams p;
  p.sensor_height_m = 1.5;
  read_scan_context(r, p);
  EXPECT_NO_THROW(r.finish());
  EXPECT_EQ(p.rings, 10);
  EXPECT_EQ(p.sectors, 30);
  EXPECT_DOUBLE_EQ(p.max_range_m, 50.0);
  EXPECT_DOUBLE_EQ(p.sensor_height_m, 1.5);
}

TEST_F(ScanContextKeys, RefuseAGridOutOfRangeAndKeepTheDefaults) {
  Reader r(yaml("scan_context:\n  rings: 0\n  sectors: 3\n  max_range_m: .nan\n"));
  const lidar::ScanContextParams defaults;
  lidar::ScanContextParams p;
  read_scan_context(r, p);
  try {
    r.finish();
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("scan_context.rings"));
    EXPECT_THAT(e.what(), HasSubstr("scan_context.sectors"));
    EXPECT_THAT(e.what(), HasSubstr("scan_context.max_range_m"));
  }
  EXPECT_EQ(p.rings, defaults.rings);
  EXPECT_EQ(p.sectors, defaults.sectors);
  EXPECT_DOUBLE_EQ(p.max_range_m, defaults.max_range_m);
}

}  // namespace
}  // namespace cdc::config
