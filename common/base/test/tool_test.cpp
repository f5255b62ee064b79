#include "cdc/base/tool.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

namespace cdc::base {
namespace {

TEST(RunTool, ReturnsTheBodysExitCode) {
  EXPECT_EQ(run_tool("t", [] { return 0; }), 0);
  EXPECT_EQ(run_tool("t", [] { return 3; }), 3);
}

TEST(RunTool, ExceptionIsPrintedWithTheToolsNameAndExitsWithOne) {
  testing::internal::CaptureStderr();
  const int code = run_tool("cdc-x", []() -> int { throw std::runtime_error("no such file"); });
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "cdc-x: no such file\n");
  EXPECT_EQ(code, 1);
}

TEST(RunTool, FailureCodeChosenFromTheException) {
  auto code_of = [](const std::exception& e) { return dynamic_cast<const std::invalid_argument*>(&e) ? 2 : 1; };
  testing::internal::CaptureStderr();
  EXPECT_EQ(run_tool(
                "t", []() -> int { throw std::invalid_argument("bad"); }, code_of),
            2);
  EXPECT_EQ(run_tool(
                "t", []() -> int { throw std::runtime_error("worse"); }, code_of),
            1);
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "t: bad\nt: worse\n");
}

}  // namespace
}  // namespace cdc::base
