// Sequence numbers of the loops the loop-closure service writes. Receivers (the central, the peers)
// drop a loop whose (sender, incarnation, seq) they already hold, and the central acknowledges per
// robot incarnation the highest seq up to which it holds every loop from 0. So the numbers start at 0
// for each incarnation and must never be used twice within one: a service restarted alone (systemd
// Restart=on-failure) under the same incarnation goes on where the last one stopped. With a state
// file, the number after each loop is saved (atomically, by rename) before the loop is written.
// No DDS; the file is the only input.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace cdc::loops {

struct LoopNumberingStats {
  uint64_t resumed = 0;        // numbering taken up from the state file (same incarnation)
  uint64_t state_errors = 0;   // state file unreadable or malformed: numbering started at 0
  uint64_t save_failures = 0;  // the state file could not be written
};

class LoopNumbering {
 public:
  // `state_path` empty: numbers are not kept across restarts. An existing file is read now; a
  // malformed one is counted (state_errors), described by last_error(), and otherwise ignored.
  explicit LoopNumbering(std::string state_path = {});

  // The sequence number of the next loop written for this incarnation; the one after it is saved
  // first. A new incarnation (the robot's sensor driver restarted) starts again at 0.
  uint32_t take(uint32_t incarnation);

  // What the state file held at start-up, if anything usable: (incarnation, next seq).
  std::optional<std::pair<uint32_t, uint32_t>> stored() const { return stored_; }
  const std::string& last_error() const { return last_error_; }
  const LoopNumberingStats& stats() const { return stats_; }

 private:
  void save();

  std::string path_;
  std::optional<std::pair<uint32_t, uint32_t>> stored_;
  std::optional<uint32_t> incarnation_;  // of the numbers being handed out
  uint32_t next_ = 0;
  std::string last_error_;
  LoopNumberingStats stats_;
};

}  // namespace cdc::loops
