// The work a loop-closure service has left (--backlog-out, LoopNodeOptions::backlog_out), kept in a
// file for a launcher that ends a mission once every loop-closure service has caught up. No DDS.
#pragma once

#include <cstdint>
#include <string>
#include <utility>

namespace cdc::loops {

struct Backlog {
  uint64_t descriptors_waiting = 0;  // to be searched, or known to exist and not received yet (gaps, a peer's tail)
  uint64_t requests_pending = 0;     // cloud requests waiting for their answer
  uint64_t requests_parked = 0;      // cloud requests waiting to be asked (again)
  uint64_t loops_published = 0;
};

// One line: "<descriptors waiting> <requests pending> <requests parked> <loops published>\n".
std::string backlog_line(const Backlog& b);

// The file holding a Backlog, replaced whenever the backlog changes: written beside it and renamed
// over it, so that a reader never sees half a line. An empty path keeps nothing.
class BacklogFile {
 public:
  explicit BacklogFile(std::string path) : path_(std::move(path)) {}

  // Writes b unless it is what the file already holds; returns whether it wrote.
  bool update(const Backlog& b);

 private:
  std::string path_;
  std::string last_;  // the line last written
};

}  // namespace cdc::loops
