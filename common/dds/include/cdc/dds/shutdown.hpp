// Clean shutdown on SIGINT/SIGTERM: a sigwait thread sets a flag and triggers guard conditions.
#pragma once

#include <atomic>
#include <functional>

namespace cdc::dds {

class GuardCondition;

class ShutdownSignal {
 public:
  // Blocks SIGINT and SIGTERM in the calling thread (and so in every thread created after it)
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
};

}  // namespace cdc::dds
