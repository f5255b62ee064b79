// YAML configuration -> plain parameter structs. A Reader collects every problem (missing file,
// wrong type, value out of range, unknown key) and finish() reports them all at once.
#pragma once

#include <yaml-cpp/yaml.h>

#include <array>
#include <cmath>
#include <functional>
#include <set>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

namespace cdc::config {

class ConfigError : public std::runtime_error {
 public:
  explicit ConfigError(const std::string& what) : std::runtime_error(what) {}
};

class Reader {
 public:
  // An empty path reads nothing: every get() returns its default.
  explicit Reader(const std::string& path);

  // Reads `key` ("a.b" for nested maps) into out when present; records an error when the value
  // has the wrong type or `valid` rejects it (`expectation` says what was expected).
  template <class T>
  void get(const std::string& key, T& out, const std::function<bool(const T&)>& valid = nullptr,
           const std::string& expectation = "") {
    known_.insert(key);
    const YAML::Node n = find(key);
    if (!n) {
      return;
    }
    T v{};
    try {
      v = n.as<T>();
    } catch (const YAML::Exception&) {
      errors_.push_back(where(key) + ": cannot read '" + YAML::Dump(n) + "' as the expected type");
      return;
    }
    if (!finite(v)) {
      errors_.push_back(where(key) + ": " + YAML::Dump(n) + " is not a finite number");
      return;
    }
    if (valid && !valid(v)) {
      errors_.push_back(where(key) + ": " + YAML::Dump(n) + " is invalid" +
                        (expectation.empty() ? std::string() : " (expected " + expectation + ")"));
      return;
    }
    out = v;
  }

  // Reads the number `key` into out when present; an error names the key, the value and the range when
  // the value lies outside [lo, hi]. Every numeric key has such a range: a value that passes must work.
  template <class T>
  void get_in(const std::string& key, T& out, T lo, T hi) {
    get<T>(
        key, out, [lo, hi](const T& v) { return v >= lo && v <= hi; }, range_text(lo, hi));
  }

  // Reads the count `key` into an unsigned field: as an int in [lo, hi], so that a negative value is
  // refused rather than wrapped round.
  template <class Count>
  void get_count(const std::string& key, Count& out, int lo, int hi) {
    int v = static_cast<int>(out);
    get_in(key, v, lo, hi);
    out = static_cast<Count>(v);
  }

  // Reads a position [x, y, z] in metres, each coordinate within [-1e7, 1e7], into out when present.
  void get_position(const std::string& key, std::array<double, 3>& out);

  // "in [lo, hi]" with the shortest exact spelling of both ends.
  static std::string range_text(double lo, double hi);

  // Adds an error found by cross-field checks.
  void error(const std::string& message) { errors_.push_back(path_ + ": " + message); }

  // Throws ConfigError listing every error and every key the program does not know.
  void finish();

 private:
  YAML::Node find(const std::string& key) const;
  // Floating-point values (alone or in a list) must be finite: YAML spells infinity and NaN as .inf and .nan.
  template <class T>
  static bool finite(const T& v) {
    if constexpr (std::is_floating_point_v<T>) {
      return std::isfinite(v);
    } else if constexpr (std::is_same_v<T, std::vector<double>>) {
      for (const double x : v) {
        if (!std::isfinite(x)) return false;
      }
      return true;
    } else {
      return true;
    }
  }
  std::string where(const std::string& key) const { return path_ + ": " + key; }
  void collect_keys(const YAML::Node& node, const std::string& prefix, std::vector<std::string>& out) const;

  std::string path_;
  YAML::Node root_;
  std::set<std::string> known_;
  std::vector<std::string> errors_;
};

}  // namespace cdc::config
