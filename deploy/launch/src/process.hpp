// Child processes of the launcher: started (optionally inside a network namespace) with their
// own log file, stopped by PID with SIGINT and, after a grace period, SIGKILL.
#pragma once

#include <sys/types.h>

#include <chrono>
#include <optional>
#include <string>
#include <vector>

namespace cdc::launch {

// SIGINT, SIGTERM and SIGHUP only set a flag: the program then stops the processes it started itself.
void install_stop_signals();
int stop_signal() noexcept;           // the signal that arrived; 0 while none has
void request_stop(int sig) noexcept;  // as if `sig` had arrived

struct CommandResult {
  int status = -1;     // exit code; 128 + signal when killed; -1 when it could not start
  std::string output;  // stdout and stderr together
};

// Runs argv[0] (searched in PATH) to completion, without a shell.
CommandResult run_command(const std::vector<std::string>& argv);
// Same, throwing std::runtime_error with the command and its output when it fails.
std::string run_checked(const std::vector<std::string>& argv);

struct ProcessSpec {
  std::string name;               // for logs and messages, e.g. "robot1/frontend"
  std::vector<std::string> argv;  // argv[0]: path of the binary
  std::vector<std::string> env;   // extra "KEY=VALUE"
  std::string netns;              // run inside this named network namespace (empty: here)
  std::string log_path;           // stdout and stderr go here
};

class Process {
 public:
  explicit Process(ProcessSpec spec);
  ~Process();  // stops the process if it still runs
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;

  const std::string& name() const noexcept { return spec_.name; }
  const ProcessSpec& spec() const noexcept { return spec_; }
  pid_t pid() const noexcept { return pid_; }
  // Non-blocking: true while the process runs (reaps it when it has ended).
  bool running();
  std::optional<int> exit_status() const noexcept { return status_; }
  void signal(int sig);
  // SIGINT, then SIGKILL after `grace`; returns the exit status.
  int stop(std::chrono::milliseconds grace);
  // Blocks until the process ends or the timeout passes; true when it ended.
  bool wait_for(std::chrono::milliseconds timeout);

 private:
  ProcessSpec spec_;
  pid_t pid_ = -1;
  std::optional<int> status_;
};

}  // namespace cdc::launch
