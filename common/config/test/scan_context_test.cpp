#include "cdc/config/scan_context.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>
#include <string>

namespace cdc::config {
namespace {

using ::testing::HasSubstr;

std::string write(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / (name + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

TEST(ScanContextKeys, ReadTheGridAndLeaveTheSensorHeight) {
  const std::string path = write("sc_keys", "scan_context:\n  rings: 10\n  sectors: 30\n  max_range_m: 50\n");
  lidar::ScanContextParams p;
  p.sensor_height_m = 1.5;
  Reader r(path);
  read_scan_context(r, p);
  EXPECT_NO_THROW(r.finish());
  EXPECT_EQ(p.rings, 10);
  EXPECT_EQ(p.sectors, 30);
  EXPECT_DOUBLE_EQ(p.max_range_m, 50.0);
  EXPECT_DOUBLE_EQ(p.sensor_height_m, 1.5);
  std::filesystem::remove(path);
}

TEST(ScanContextKeys, RefuseAGridOutOfRangeAndKeepTheDefaults) {
  const std::string path = write("sc_bad", "scan_context:\n  rings: 0\n  sectors: 3\n  max_range_m: .nan\n");
  const lidar::ScanContextParams defaults;
  lidar::ScanContextParams p;
  Reader r(path);
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
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace cdc::config
