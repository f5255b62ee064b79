// Starts and ends helper processes for multi-process tests. Only ever signals the PIDs it
// started itself.
#pragma once

#include <sys/types.h>
#include <chrono>
#include <initializer_list>
#include <optional>
#include <string>
#include <vector>

namespace cdc::test {

class ChildProcess {
 public:
  // Starts argv[0] with the given arguments and the current environment; when log_path is given,
  // the child's stdout and stderr go to that file.
  static ChildProcess spawn(const std::vector<std::string>& argv, const std::string& log_path = "");

  ChildProcess() = default;
  ~ChildProcess();  // SIGKILLs and reaps a child still running
  ChildProcess(ChildProcess&& other) noexcept;
  ChildProcess& operator=(ChildProcess&& other) noexcept;
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  pid_t pid() const noexcept { return pid_; }
  bool running() const noexcept { return pid_ > 0; }
  void signal(int sig) const;
  // Waits for exit; returns the raw wait status, or nullopt on timeout.
  std::optional<int> wait(std::chrono::milliseconds timeout);
  // Ends a child still running: SIGTERM, then SIGKILL when it has not exited within grace. Returns the
  // wait status; nullopt when no child was running, or it outlived the SIGKILL by 5 s.
  std::optional<int> stop(std::chrono::milliseconds grace);

 private:
  pid_t pid_ = -1;
};

// Asks each process to end (SIGTERM), then waits up to timeout for each in turn; true when all ended.
bool terminate_all(std::initializer_list<ChildProcess*> processes, std::chrono::milliseconds timeout);

}  // namespace cdc::test
