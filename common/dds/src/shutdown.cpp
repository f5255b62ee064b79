#include "cdc/dds/shutdown.hpp"

#include "cdc/dds/waitset.hpp"

#include <csignal>
#include <mutex>
#include <pthread.h>
#include <thread>
#include <vector>

namespace cdc::dds {
namespace {

std::atomic<bool> g_requested{false};
std::atomic<int> g_signal{0};
std::mutex g_mutex;
std::vector<GuardCondition*> g_guards;
std::once_flag g_once;

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
    pthread_sigmask(SIG_BLOCK, &set, nullptr);
    std::thread([set] {
      int sig = 0;
      if (sigwait(&set, &sig) == 0) {
        g_signal.store(sig);
        request();
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

}  // namespace cdc::dds
