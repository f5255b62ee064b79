#include "cdc/config/reader.hpp"
#include "cdc/config/cli_range.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <unistd.h>
#include <array>
#include <filesystem>
#include <fstream>
#include <vector>

namespace cdc::config {
namespace {

std::string write(const std::string& name, const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / (name + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

// The message of the ConfigError that finish() throws; a test failure and "" when it throws none.
std::string finish_error(Reader& r) {
  try {
    r.finish();
  } catch (const ConfigError& e) {
    return e.what();
  }
  ADD_FAILURE() << "no error";
  return "";
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
  const std::string m = finish_error(r);
  EXPECT_THAT(m, ::testing::HasSubstr("range_m: -5 is invalid (expected a positive range in metres)"));
  EXPECT_THAT(m, ::testing::HasSubstr("dwell_ms: cannot read 'soon'"));
  EXPECT_THAT(m, ::testing::HasSubstr("range_mm: unknown setting"));
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

// YAML spells infinity and NaN as .inf and .nan: no number a program reads may be either, and a range names
// itself in the error.
TEST(ConfigReader, NonFiniteNumbersAndValuesOutOfRangeAreRefused) {
  const std::string p = write("finite", "a: .inf\nb: .nan\nc: -.inf\nd: 1e12\ne: 5\nf: [1, .nan, 3]\ng: 7\n");
  Reader r(p);
  double a = 1, b = 2, c = 3, d = 4, e = 0;
  std::vector<double> f{0, 0, 0};
  int g = 1;
  r.get<double>("a", a);
  r.get<double>("b", b);
  r.get<double>("c", c);
  r.get_in("d", d, 0.0, 1000.0);
  r.get_in("e", e, 0.0, 10.0);
  r.get<std::vector<double>>("f", f);
  r.get_in("g", g, 1, 5);
  const std::string m = finish_error(r);
  EXPECT_THAT(m, ::testing::HasSubstr("a: .inf is not a finite number"));
  EXPECT_THAT(m, ::testing::HasSubstr("b: .nan is not a finite number"));
  EXPECT_THAT(m, ::testing::HasSubstr("c: -.inf is not a finite number"));
  EXPECT_THAT(m, ::testing::HasSubstr("d: 1e12 is invalid (expected in [0, 1000])"));
  EXPECT_THAT(m, ::testing::HasSubstr("is not a finite number"));
  EXPECT_THAT(m, ::testing::HasSubstr("g: 7 is invalid (expected in [1, 5])"));
  EXPECT_THAT(m, ::testing::Not(::testing::HasSubstr("e:")));
  EXPECT_EQ(a, 1);
  EXPECT_EQ(d, 4);
  EXPECT_EQ(e, 5);  // in range: read
  EXPECT_EQ(g, 1);
  std::filesystem::remove(p);
}

// Counts land in unsigned fields through an int, so "-1" is refused rather than wrapped; a position is
// three numbers, each within 1e7 m of the origin.
TEST(ConfigReader, CountsAndPositionsAreChecked) {
  const std::string p = write("count", "a: 5\nb: -1\nc: [1, 2, 3]\nd: [1, 2]\ne: [0, 0, 1e8]\n");
  Reader r(p);
  uint32_t a = 1, b = 2;
  std::array<double, 3> c{0, 0, 0}, d{0, 0, 0}, e{0, 0, 0};
  r.get_count("a", a, 0, 10);
  r.get_count("b", b, 0, 10);
  r.get_position("c", c);
  r.get_position("d", d);
  r.get_position("e", e);
  const std::string m = finish_error(r);
  EXPECT_THAT(m, ::testing::HasSubstr("b: -1 is invalid (expected in [0, 10])"));
  EXPECT_THAT(m, ::testing::HasSubstr("d: [1, 2] is invalid (expected [x, y, z], each in [-1e7, 1e7] m)"));
  EXPECT_THAT(m, ::testing::HasSubstr("e: [0, 0, 1e8] is invalid"));
  EXPECT_EQ(a, 5u);
  EXPECT_EQ(b, 2u);
  EXPECT_EQ(c, (std::array<double, 3>{1, 2, 3}));
  EXPECT_EQ(d, (std::array<double, 3>{0, 0, 0}));
  EXPECT_EQ(e, (std::array<double, 3>{0, 0, 0}));
  std::filesystem::remove(p);
}

// The command-line check: NaN, infinities, text and values outside the range are refused naming the option;
// "-1" for an unsigned option is refused rather than read as its largest value.
TEST(CliRange, RefusesWhatIsNotAFiniteNumberInRange) {
  const auto parse = [](const std::vector<std::string>& args) -> std::string {
    CLI::App app{"t"};
    double rate = 1;
    size_t scans = 0;
    app.add_option("--rate", rate)->check(cli_range(0, 1000));
    app.add_option("--max-scans", scans)->check(cli_range(0, 1e6));
    std::vector<std::string> argv(args.rbegin(), args.rend());
    try {
      app.parse(argv);
    } catch (const CLI::ParseError& e) {
      return e.what();
    }
    return "accepted";
  };
  EXPECT_EQ(parse({"--rate", "2.5"}), "accepted");
  EXPECT_EQ(parse({"--max-scans", "0"}), "accepted");
  EXPECT_THAT(parse({"--rate", "nan"}),
              ::testing::HasSubstr("--rate: 'nan' is not a finite number (expected in [0, 1000])"));
  EXPECT_THAT(parse({"--rate", "inf"}), ::testing::HasSubstr("'inf' is not a finite number"));
  EXPECT_THAT(parse({"--rate", "-1"}),
              ::testing::HasSubstr("--rate: -1 is outside the allowed range (expected in [0, 1000])"));
  EXPECT_THAT(parse({"--rate", "fast"}), ::testing::HasSubstr("'fast' is not a finite number"));
  EXPECT_THAT(parse({"--max-scans", "-1"}), ::testing::HasSubstr("--max-scans: -1 is outside the allowed range"));
}

}  // namespace
}  // namespace cdc::config
