// A fixture for tests that run service binaries as child processes and watch them over DDS (header
// only; users link cdc_dds and cdc_test_support).
#pragma once

#include "cdc/dds/participant.hpp"
#include "dds_helpers.hpp"
#include "temp_dir.hpp"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace cdc::test {

// Every test fails at once unless the environment variables naming its binaries are set. It gets an
// empty folder dir_ (fresh_test_dir(name)) for the processes' configuration, output and logs, removed
// after a passing test and kept, and named, after a failing one; and participant_ on the test's DDS
// domain. A subclass adds its own set-up in set_up() (readers and writers on participant_) and ends
// its processes in stop_processes(), before dir_ goes.
class ProcessTest : public ::testing::Test {
 protected:
  ProcessTest(std::string name, std::vector<std::string> binaries)
      : name_(std::move(name)), binaries_(std::move(binaries)) {}

  virtual void set_up() {}
  virtual void stop_processes() {}

  void SetUp() final {
    for (const std::string& v : binaries_) {
      ASSERT_NE(std::getenv(v.c_str()), nullptr) << v << " must name the binary";
    }
    dir_ = fresh_test_dir(name_);
    participant_ = std::make_unique<dds::Participant>(test_domain());
    set_up();
  }

  void TearDown() final {
    stop_processes();
    if (dir_.empty()) return;
    if (!HasFailure()) {
      std::filesystem::remove_all(dir_);
    } else {
      std::printf("logs kept in %s\n", dir_.c_str());
    }
  }

  // The path of a file in dir_.
  std::string path(const std::string& file) const { return (dir_ / file).string(); }

  // Writes `text` to a file in dir_; its path.
  std::string write(const std::string& file, const std::string& text) const {
    std::ofstream(path(file)) << text;
    return path(file);
  }

  std::filesystem::path dir_;
  std::unique_ptr<dds::Participant> participant_;

 private:
  std::string name_;
  std::vector<std::string> binaries_;
};

}  // namespace cdc::test
