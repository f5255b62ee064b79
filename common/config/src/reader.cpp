#include "cdc/config/reader.hpp"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>

namespace cdc::config {

Reader::Reader(const std::string& path) : path_(path.empty() ? "<defaults>" : path) {
  if (path.empty()) {
    return;
  }
  if (!std::filesystem::exists(path)) {
    errors_.push_back(path + ": file not found");
    return;
  }
  try {
    root_ = YAML::LoadFile(path);
  } catch (const YAML::Exception& e) {
    errors_.push_back(path + ": YAML error at line " + std::to_string(e.mark.line + 1) + ": " + e.msg);
  }
  if (root_ && !root_.IsMap() && !root_.IsNull()) {
    errors_.push_back(path + ": the top level must be a map of settings");
    root_ = YAML::Node();
  }
}

YAML::Node Reader::find(const std::string& key) const {
  if (!root_ || !root_.IsMap()) {
    return YAML::Node(YAML::NodeType::Undefined);
  }
  YAML::Node n = YAML::Clone(root_);
  std::stringstream ss(key);
  std::string part;
  while (std::getline(ss, part, '.')) {
    if (!n.IsMap() || !n[part]) {
      return YAML::Node(YAML::NodeType::Undefined);
    }
    n = n[part];
  }
  return n;
}

void Reader::collect_keys(const YAML::Node& node, const std::string& prefix, std::vector<std::string>& out) const {
  for (const auto& kv : node) {
    const std::string k = prefix.empty() ? kv.first.as<std::string>() : prefix + "." + kv.first.as<std::string>();
    if (kv.second.IsMap() && known_.count(k) == 0) {
      collect_keys(kv.second, k, out);
    } else {
      out.push_back(k);
    }
  }
}

void Reader::get_position(const std::string& key, std::array<double, 3>& out) {
  std::vector<double> v(out.begin(), out.end());
  get<std::vector<double>>(
      key, v,
      [](const std::vector<double>& xyz) {
        return xyz.size() == 3 && std::all_of(xyz.begin(), xyz.end(), [](double x) { return std::abs(x) <= 1e7; });
      },
      "[x, y, z], each in [-1e7, 1e7] m");
  std::copy(v.begin(), v.end(), out.begin());
}

std::string Reader::range_text(double lo, double hi) {
  char text[80];
  std::snprintf(text, sizeof text, "in [%.10g, %.10g]", lo, hi);
  return text;
}

void Reader::finish() {
  if (root_ && root_.IsMap()) {
    std::vector<std::string> keys;
    collect_keys(root_, "", keys);
    for (const auto& k : keys) {
      if (known_.count(k) == 0) {
        errors_.push_back(where(k) + ": unknown setting");
      }
    }
  }
  if (errors_.empty()) {
    return;
  }
  std::string msg = "invalid configuration:";
  for (const auto& e : errors_) {
    msg += "\n  " + e;
  }
  throw ConfigError(msg);
}

}  // namespace cdc::config
