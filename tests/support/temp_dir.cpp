#include "temp_dir.hpp"

#include <unistd.h>
#include <fstream>
#include <iterator>

namespace cdc::test {

namespace fs = std::filesystem;

namespace {

fs::path fresh(const std::string& leaf) {
  const fs::path d = fs::temp_directory_path() / leaf;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

}  // namespace

fs::path fresh_temp_dir(const std::string& name) { return fresh("cdc_" + name + "_" + std::to_string(::getpid())); }

fs::path fresh_test_dir(const std::string& name) {
  const ::testing::TestInfo* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string test = info != nullptr ? info->name() : "none";
  return fresh("cdc_" + name + "_" + test + "_" + std::to_string(::getpid()));
}

std::string read_file(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace cdc::test
