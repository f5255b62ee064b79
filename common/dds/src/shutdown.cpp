#include "cdc/dds/shutdown.hpp"

#include "cdc/dds/waitset.hpp"

#include <pthread.h>
#include <csignal>
#include <mutex>
#include <thread>
#include <vector>

namespace cdc::dds {
namespace {

std::atomic<bool> g_requested{false};
std::atomic<int> g_signal{0};
std::mutex g_mutex;
std::vector<GuardCondition*> g_guards;
std::once_flag g_once;
std::mutex g_user_mutex;
std::function<void(int)> g_user;

void trigger_all() {
  std::lock_guard<std::mutex> lock(g_mutex);
  for (GuardCondition* g : g_guards) {
    try {
      g->trigger();
    } catch (...) {
      // The condition's participant is being torn down; the flag still says "stop".
    }
  }
}

}  // namespace

void ShutdownSignal::install() {
  std::call_once(g_once, [] {
    sigset_t set;
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    sigaddset(&set, SIGUSR1);
    sigaddset(&set, SIGUSR2);
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    std::thread([set] {
      while (true) {
        int sig = 0;
        if (sigwait(&set, &sig) != 0) continue;
        if (sig == SIGUSR1 || sig == SIGUSR2) {
          std::lock_guard<std::mutex> lock(g_user_mutex);
          if (g_user) {
            try {
              g_user(sig);
            } catch (...) {
              // A failing handler must not end the signal thread (shutdown still works).
            }
          }
          continue;
        }
        g_signal.store(sig);
        request();
        return;
      }
    }).detach();
  });
}

bool ShutdownSignal::requested() noexcept { return g_requested.load(); }

void ShutdownSignal::request() noexcept {
  g_requested.store(true);
  trigger_all();
}

void ShutdownSignal::add_guard(GuardCondition* guard) {
  {
    std::lock_guard<std::mutex> lock(g_mutex);
    g_guards.push_back(guard);
  }
  if (requested()) {
    guard->trigger();
  }
}

void ShutdownSignal::remove_guard(GuardCondition* guard) {
  std::lock_guard<std::mutex> lock(g_mutex);
  std::erase(g_guards, guard);
}

int ShutdownSignal::signal_number() noexcept { return g_signal.load(); }

void ShutdownSignal::on_user_signal(std::function<void(int signal)> handler) {
  std::lock_guard<std::mutex> lock(g_user_mutex);
  g_user = std::move(handler);
}

}  // namespace cdc::dds
