// Scratch folders for tests: one per process (and per test where asked), emptied on creation.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <string>
#include <utility>

namespace cdc::test {

// Makes the empty folder <temp>/cdc_<name>_<pid>, removing whatever stood there, and returns it.
std::filesystem::path fresh_temp_dir(const std::string& name);

// The same, named also after the running gtest test: <temp>/cdc_<name>_<test>_<pid>.
std::filesystem::path fresh_test_dir(const std::string& name);

// The whole content of a file, byte for byte (empty when it cannot be read).
std::string read_file(const std::filesystem::path& path);

// A fixture whose tests each get an empty folder dir_ (fresh_temp_dir(name)), removed after the test.
// With `required_env`, a test fails at once unless that environment variable is set.
class TempDirTest : public ::testing::Test {
 protected:
  explicit TempDirTest(std::string name, std::string required_env = "")
      : name_(std::move(name)), required_env_(std::move(required_env)) {}
  void SetUp() override {
    if (!required_env_.empty()) {
      ASSERT_NE(std::getenv(required_env_.c_str()), nullptr) << required_env_;
    }
    dir_ = fresh_temp_dir(name_);
  }
  void TearDown() override {
    if (!dir_.empty()) std::filesystem::remove_all(dir_);
  }
  // The path of a file in dir_.
  std::string path(const std::string& file) const { return (dir_ / file).string(); }

  std::filesystem::path dir_;

 private:
  std::string name_;
  std::string required_env_;
};

}  // namespace cdc::test
