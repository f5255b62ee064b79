// A fixture for tests that run a helper binary, named by an environment variable, on the test's DDS
// domain (header only; users link cdc_dds and gtest).
#pragma once

#include "cdc/dds/participant.hpp"
#include "cdc/dds/shutdown.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <string>
#include <utility>

namespace cdc::test {

class HelperProcessTest : public ::testing::Test {
 protected:
  explicit HelperProcessTest(std::string env_var) : env_var_(std::move(env_var)) {}

  // Before any DDS thread exists, as a service's main() does: every later thread blocks the
  // signals, so that the signal thread alone takes SIGUSR1/SIGUSR2.
  static void SetUpTestSuite() { dds::ShutdownSignal::install(); }
  void SetUp() override {
    const char* exe = std::getenv(env_var_.c_str());
    ASSERT_NE(exe, nullptr) << env_var_ << " must name the helper binary";
    exe_ = exe;
    domain_ = dds::domain_from_env(0);
  }

  std::string exe_;      // the helper binary
  uint32_t domain_ = 0;  // the test's DDS domain (CDC_DDS_DOMAIN, else 0)

 private:
  std::string env_var_;
};

}  // namespace cdc::test
