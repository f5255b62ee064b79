#include "backlog_file.hpp"

#include <cstdio>
#include <fstream>

namespace cdc::loops {

std::string backlog_line(const Backlog& b) {
  return std::to_string(b.descriptors_waiting) + ' ' + std::to_string(b.requests_pending) + ' ' +
         std::to_string(b.requests_parked) + ' ' + std::to_string(b.loops_published) + '\n';
}

bool BacklogFile::update(const Backlog& b) {
  if (path_.empty()) return false;
  std::string line = backlog_line(b);
  if (line == last_) return false;
  const std::string tmp = path_ + ".tmp";
  std::ofstream(tmp, std::ios::trunc) << line;
  std::rename(tmp.c_str(), path_.c_str());
  last_ = std::move(line);
  return true;
}

}  // namespace cdc::loops
