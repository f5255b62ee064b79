#include "cdc/eval/evaluation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

namespace cdc::eval {
namespace {

geometry::Trajectory circle(double radius, int n, double z_offset = 0.0) {
  geometry::Trajectory t;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(radius * std::cos(a), radius * std::sin(a), z_offset);
    T.linear() = Eigen::AngleAxisd(a + M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    t.push_back({i * 100'000'000LL, T});
  }
  return t;
}

TEST(Evaluation, MatchesByTimeAndReportsZeroForIdenticalTrajectories) {
  const auto gt = circle(50, 200);
  auto est = gt;
  for (auto& p : est) {
    p.stamp_ns += 2'000'000;  // 2 ms late: still matched
  }
  const Evaluation e = evaluate("same", est, gt, EvalOptions{});
  EXPECT_EQ(e.matched, 200u);
  EXPECT_LT(e.ate.translation.rmse, 1e-9);
  EXPECT_NEAR(e.gt_length_m, 2 * M_PI * 50 * 199.0 / 200.0, 0.1);
  const auto j = to_json(e, EvalOptions{});
  EXPECT_EQ(j["poses"]["matched"], 200);
  EXPECT_NEAR(j["ate_m"]["rmse"].get<double>(), 0.0, 1e-9);
}

TEST(Evaluation, TooFewMatchesIsAnError) {
  const auto gt = circle(50, 20);
  auto est = gt;
  for (auto& p : est) {
    p.stamp_ns += 50'000'000;  // 50 ms off, tolerance 10 ms
  }
  EXPECT_THROW(evaluate("late", est, gt, EvalOptions{}), std::runtime_error);
}

TEST(Evaluation, SvgShowsBothTrajectoriesAndEscapesNames) {
  const auto gt = circle(50, 100);
  const auto est = circle(51, 100, 0.5);
  const Evaluation e = evaluate("robot <1>", est, gt, EvalOptions{});
  const std::string svg = render_svg({e}, "auto", "a & b");
  EXPECT_THAT(svg, ::testing::StartsWith("<svg"));
  EXPECT_EQ(std::count(svg.begin(), svg.end(), 'p') > 0, true);
  size_t polylines = 0;
  for (size_t pos = svg.find("<polyline"); pos != std::string::npos; pos = svg.find("<polyline", pos + 1)) {
    ++polylines;
  }
  EXPECT_EQ(polylines, 2u);
  EXPECT_THAT(svg, ::testing::HasSubstr("robot &lt;1&gt;"));
  EXPECT_THAT(svg, ::testing::HasSubstr("a &amp; b"));
  EXPECT_THAT(svg, ::testing::HasSubstr("x right, y up"));
  EXPECT_THROW(render_svg({e}, "zz", ""), std::invalid_argument);
}

TEST(Evaluation, TableHasOneRowPerTrajectory) {
  const auto gt = circle(50, 100);
  const Evaluation a = evaluate("a", gt, gt, EvalOptions{});
  const Evaluation b = evaluate("b", circle(52, 100), gt, EvalOptions{});
  const std::string table = format_table({a, b});
  EXPECT_EQ(std::count(table.begin(), table.end(), '\n'), 3);
  EXPECT_THAT(table, ::testing::HasSubstr("ATE_rmse"));
}

}  // namespace
}  // namespace cdc::eval
