#include "cdc/loop_closure/loop_numbering.hpp"

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

namespace cdc::loops {
namespace {

constexpr const char* kHeader = "cdc-loop-numbering 1";

// "<key> <unsigned 32-bit>" on one line, or an error naming what is wrong.
bool parse_field(std::istream& in, const char* key, uint32_t& value, std::string& error) {
  std::string line;
  if (!std::getline(in, line)) {
    error = std::string("missing line '") + key + " N'";
    return false;
  }
  std::istringstream ls(line);
  std::string k;
  unsigned long long v = 0;
  std::string rest;
  if (!(ls >> k) || k != key || !(ls >> v) || (ls >> rest) || v > std::numeric_limits<uint32_t>::max() ||
      line.find('-') != std::string::npos) {
    error = std::string("line '") + line + "' is not '" + key + " N' (N an unsigned 32-bit number)";
    return false;
  }
  value = static_cast<uint32_t>(v);
  return true;
}

}  // namespace

LoopNumbering::LoopNumbering(std::string state_path) : path_(std::move(state_path)) {
  std::error_code ec;
  if (path_.empty() || (!std::filesystem::exists(path_, ec) && !ec)) {
    return;  // no file yet: the first run under this path
  }
  std::ifstream in(path_);
  std::string header, error;
  uint32_t incarnation = 0, next = 0;
  if (ec) {
    error = "cannot be looked up: " + ec.message();
  } else if (!in) {
    error = "cannot be read: " + std::string(std::strerror(errno));
  } else if (!std::getline(in, header) || header != kHeader) {
    error = "first line is not '" + std::string(kHeader) + "'";
  } else if (parse_field(in, "incarnation", incarnation, error) && parse_field(in, "next_seq", next, error)) {
    stored_ = {incarnation, next};
    return;
  }
  last_error_ = "loop numbering state " + path_ + ": " + error + "; numbering starts at 0";
  ++stats_.state_errors;
}

uint32_t LoopNumbering::take(uint32_t incarnation) {
  if (incarnation_ != incarnation) {
    incarnation_ = incarnation;
    next_ = 0;
    if (stored_ && stored_->first == incarnation) {
      next_ = stored_->second;
      ++stats_.resumed;
    }
  }
  const uint32_t seq = next_++;
  save();
  return seq;
}

void LoopNumbering::save() {
  if (path_.empty()) {
    return;
  }
  const std::string tmp = path_ + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    out << kHeader << "\nincarnation " << *incarnation_ << "\nnext_seq " << next_ << '\n';
    out.flush();
    if (!out) {
      last_error_ = "loop numbering state " + tmp + " cannot be written: " + std::strerror(errno);
      ++stats_.save_failures;
      return;
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path_, ec);
  if (ec) {
    last_error_ = "loop numbering state " + path_ + " cannot be replaced: " + ec.message();
    ++stats_.save_failures;
  }
}

}  // namespace cdc::loops
