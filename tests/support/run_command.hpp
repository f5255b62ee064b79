// Runs a shell command and captures what it prints, for tests of command-line tools.
#pragma once

#include <string>

namespace cdc::test {

struct CommandResult {
  int exit_code = -1;  // -1: it could not be started or did not exit normally
  std::string output;  // stdout, and stderr too when merged
};

// `command` through /bin/sh; stderr is appended to stdout (2>&1) unless merge_stderr is false.
CommandResult run_command(const std::string& command, bool merge_stderr = true);

}  // namespace cdc::test
