#include "process.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <thread>

namespace cdc::launch {
namespace {

std::atomic<int> g_stop_signal{0};
extern "C" void on_stop_signal(int sig) { g_stop_signal = sig; }

std::vector<char*> c_argv(std::vector<std::string>& args) {
  std::vector<char*> out;
  for (std::string& a : args) out.push_back(a.data());
  out.push_back(nullptr);
  return out;
}

int decode(int wstatus) {
  if (WIFEXITED(wstatus)) return WEXITSTATUS(wstatus);
  if (WIFSIGNALED(wstatus)) return 128 + WTERMSIG(wstatus);
  return -1;
}

// In the child after fork: only async-signal-safe calls until exec.
[[noreturn]] void exec_child(std::vector<std::string> args, int out_fd) {
  // The launcher blocks SIGINT/SIGTERM while it runs; children start with the default mask.
  sigset_t none;
  sigemptyset(&none);
  sigprocmask(SIG_SETMASK, &none, nullptr);
  setpgid(0, 0);  // a terminal's Ctrl-C reaches the launcher only; it stops the children itself
  if (out_fd >= 0) {
    dup2(out_fd, STDOUT_FILENO);
    dup2(out_fd, STDERR_FILENO);
    close(out_fd);
  }
  const int devnull = open("/dev/null", O_RDONLY);
  if (devnull >= 0) dup2(devnull, STDIN_FILENO);
  std::vector<char*> argv = c_argv(args);
  execvp(argv[0], argv.data());
  const char* msg = "cdc-launch: cannot execute ";
  (void)!write(STDERR_FILENO, msg, std::strlen(msg));
  (void)!write(STDERR_FILENO, argv[0], std::strlen(argv[0]));
  (void)!write(STDERR_FILENO, "\n", 1);
  _exit(127);
}

}  // namespace

void install_stop_signals() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  for (int s : {SIGINT, SIGTERM, SIGHUP}) sigaction(s, &sa, nullptr);
}

int stop_signal() noexcept { return g_stop_signal.load(); }
void request_stop(int sig) noexcept { g_stop_signal = sig; }

CommandResult run_command(const std::vector<std::string>& argv) {
  CommandResult r;
  int pipefd[2];
  if (pipe2(pipefd, O_CLOEXEC) != 0) return r;
  const pid_t pid = fork();
  if (pid < 0) {
    close(pipefd[0]);
    close(pipefd[1]);
    return r;
  }
  if (pid == 0) {
    close(pipefd[0]);
    const int fd = dup(pipefd[1]);
    exec_child(argv, fd);
  }
  close(pipefd[1]);
  char buf[4096];
  ssize_t n;
  while ((n = read(pipefd[0], buf, sizeof buf)) > 0 || (n < 0 && errno == EINTR)) {
    if (n > 0) r.output.append(buf, static_cast<size_t>(n));
  }
  close(pipefd[0]);
  int ws = 0;
  while (waitpid(pid, &ws, 0) < 0 && errno == EINTR) {}
  r.status = decode(ws);
  return r;
}

std::string run_checked(const std::vector<std::string>& argv) {
  const CommandResult r = run_command(argv);
  if (r.status != 0) {
    std::string cmd;
    for (const auto& a : argv) cmd += (cmd.empty() ? "" : " ") + a;
    throw std::runtime_error("'" + cmd + "' failed (exit " + std::to_string(r.status) + "): " + r.output);
  }
  return r.output;
}

Process::Process(ProcessSpec spec) : spec_(std::move(spec)) {
  std::vector<std::string> args;
  if (!spec_.netns.empty()) args = {"ip", "netns", "exec", spec_.netns};
  if (!spec_.env.empty()) {
    args.push_back("env");
    for (const auto& e : spec_.env) args.push_back(e);
  }
  args.insert(args.end(), spec_.argv.begin(), spec_.argv.end());
  int fd = -1;
  if (!spec_.log_path.empty()) {
    fd = open(spec_.log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw std::runtime_error(spec_.log_path + ": cannot open the log file: " + std::strerror(errno));
  }
  pid_ = fork();
  if (pid_ < 0) {
    if (fd >= 0) close(fd);
    throw std::runtime_error(spec_.name + ": fork failed: " + std::strerror(errno));
  }
  if (pid_ == 0) {
    const int keep = fd >= 0 ? dup(fd) : -1;  // without O_CLOEXEC
    exec_child(args, keep);
  }
  if (fd >= 0) close(fd);
}

Process::~Process() {
  if (pid_ > 0 && !status_) stop(std::chrono::seconds(5));
}

bool Process::running() {
  if (pid_ <= 0 || status_) return false;
  int ws = 0;
  const pid_t r = waitpid(pid_, &ws, WNOHANG);
  if (r == pid_) {
    status_ = decode(ws);
    return false;
  }
  return r == 0;
}

void Process::signal(int sig) {
  if (running()) kill(pid_, sig);
}

bool Process::wait_for(std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (running()) {
    if (std::chrono::steady_clock::now() >= deadline) return false;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return true;
}

int Process::stop(std::chrono::milliseconds grace) {
  signal(SIGINT);
  if (!wait_for(grace)) {
    signal(SIGKILL);
    wait_for(std::chrono::seconds(5));
  }
  return status_.value_or(-1);
}

}  // namespace cdc::launch
