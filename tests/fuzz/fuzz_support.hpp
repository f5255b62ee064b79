// Helpers the harnesses share. Most readers take a path, so an input becomes a file in a folder of
// this process's own (removed at exit); the first input byte can pick which variant of a parser the
// rest exercises. A harness lets only std::runtime_error (the readers' documented "bad input" error,
// YAML::Exception included) pass: anything else escaping a reader is a finding, as are the
// sanitizers' reports.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>

namespace cdc::fuzz {

class ScratchDir {
 public:
  ScratchDir() {
    std::string templ = (std::filesystem::temp_directory_path() / "cdc-fuzz-XXXXXX").string();
    if (mkdtemp(templ.data()) == nullptr) std::abort();
    path_ = templ;
  }
  ~ScratchDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

inline const std::filesystem::path& scratch_dir() {
  static const ScratchDir dir;
  return dir.path();
}

// Writes `bytes` to `name` (a relative path, folders created) in the scratch folder; returns its path.
inline std::filesystem::path write_file(const std::string& name, std::span<const uint8_t> bytes) {
  const std::filesystem::path p = scratch_dir() / name;
  std::filesystem::create_directories(p.parent_path());
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) std::abort();
  return p;
}

// An input split into a selector (its first byte, 0 when empty) and the rest.
struct Input {
  uint8_t selector = 0;
  std::span<const uint8_t> rest;

  Input(const uint8_t* data, size_t size) {
    if (size > 0) {
      selector = data[0];
      rest = std::span<const uint8_t>(data + 1, size - 1);
    }
  }
  std::string_view text() const { return {reinterpret_cast<const char*>(rest.data()), rest.size()}; }
};

// Runs f(), letting std::runtime_error (a reader's refusal of bad input) pass.
template <class F>
void refusals_pass(F&& f) {
  try {
    f();
  } catch (const std::runtime_error&) {}
}

}  // namespace cdc::fuzz
