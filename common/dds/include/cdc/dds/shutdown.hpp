// The process's signals, handled on one sigwait thread: SIGINT/SIGTERM ask for a clean shutdown
// (a flag and guard conditions); SIGUSR1/SIGUSR2 go to the handler the program registers (the map
// writes its files on SIGUSR1; a robot's services take them as the loopback launcher's emulated
// radio, see robot_domains.hpp).
#pragma once

#include <atomic>
#include <functional>

namespace cdc::dds {

class GuardCondition;

class ShutdownSignal {
 public:
  // Blocks SIGINT, SIGTERM, SIGUSR1 and SIGUSR2 in the calling thread (and so in every thread created after it)
  // and starts the thread that waits for them. Call first thing in main(), before DDS starts
  // its threads. Calling again has no further effect.
  static void install();

  // True once a signal arrived or request() was called.
  static bool requested() noexcept;

  // Asks for shutdown from inside the program (same effect as a signal).
  static void request() noexcept;

  // Triggered when shutdown is requested (immediately if it already was). The condition must
  // outlive the program's work loop; unregister before destroying it.
  static void add_guard(GuardCondition* guard);
  static void remove_guard(GuardCondition* guard);

  // The signal number received, 0 if none.
  static int signal_number() noexcept;

  // Called on the signal thread with the signal number for each SIGUSR1 and SIGUSR2. Without a
  // handler both are ignored. Replaces any earlier handler; an empty function removes it.
  static void on_user_signal(std::function<void(int signal)> handler);
};

}  // namespace cdc::dds
