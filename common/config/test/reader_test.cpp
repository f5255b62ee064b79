#include "cdc/config/reader.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

namespace cdc::config {
namespace {

std::string write(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / (name + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

TEST(ConfigReader, ReadsNestedValuesAndKeepsDefaults) {
  const std::string p = write("ok", "range_m: 150\nfusion:\n  pos_max_m: 0.2\n");
  Reader r(p);
  double range = 100, pos = 0.1, rot = 1.0;
  r.get<double>(
      "range_m", range, [](const double& v) { return v > 0; }, "> 0");
  r.get<double>("fusion.pos_max_m", pos);
  r.get<double>("fusion.rot_max_deg", rot);
  EXPECT_NO_THROW(r.finish());
  EXPECT_DOUBLE_EQ(range, 150);
  EXPECT_DOUBLE_EQ(pos, 0.2);
  EXPECT_DOUBLE_EQ(rot, 1.0);
  std::filesystem::remove(p);
}

TEST(ConfigReader, ListsEveryErrorAtOnce) {
  const std::string p = write("bad", "range_m: -5\ndwell_ms: soon\nrange_mm: 3\n");
  Reader r(p);
  double range = 100;
  int dwell = 3000;
  r.get<double>(
      "range_m", range, [](const double& v) { return v > 0; }, "a positive range in metres");
  r.get<int>("dwell_ms", dwell);
  try {
    r.finish();
    FAIL();
  } catch (const ConfigError& e) {
    const std::string m = e.what();
    EXPECT_THAT(m, ::testing::HasSubstr("range_m: -5 is invalid (expected a positive range in metres)"));
    EXPECT_THAT(m, ::testing::HasSubstr("dwell_ms: cannot read 'soon'"));
    EXPECT_THAT(m, ::testing::HasSubstr("range_mm: unknown setting"));
  }
  EXPECT_DOUBLE_EQ(range, 100);  // invalid values never replace the default
  std::filesystem::remove(p);
}

TEST(ConfigReader, MissingFileAndSyntaxErrorsAreReported) {
  Reader missing("/nonexistent/cdc.yaml");
  EXPECT_THROW(missing.finish(), ConfigError);
  const std::string p = write("syntax", "a: [1, 2\n");
  Reader bad(p);
  EXPECT_THAT([&] { bad.finish(); }, ::testing::ThrowsMessage<ConfigError>(::testing::HasSubstr("YAML error at line")));
  std::filesystem::remove(p);
  Reader none("");
  EXPECT_NO_THROW(none.finish());
}

}  // namespace
}  // namespace cdc::config
