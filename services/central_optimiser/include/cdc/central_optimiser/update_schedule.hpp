// When the central optimises and when it publishes what it found. No DDS: the node asks it on every
// pass of its loop with the time now.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace cdc::central {

class UpdateSchedule {
 public:
  using Clock = std::chrono::steady_clock;

  // update_period: least time between optimisations; max_result_age: results of a graph that has not
  // settled are held back at most this long.
  UpdateSchedule(std::chrono::milliseconds update_period, std::chrono::milliseconds max_result_age);

  // An optimisation is due: the graph changed or has not settled, and the update period has passed.
  bool update_due(bool dirty, bool settled, Clock::time_point now) const;

  // Records an optimisation at `now` whose graph has (or has not) settled; true when its results go
  // out. A graph that has not settled (a bounded pass after a large change, such as a robot's re-sent
  // backlog) is a partial solution: its results are held back, so that the robots' front-ends never
  // follow it and then turn back, unless the last results published are getting old.
  bool updated(bool settled, Clock::time_point now);

  uint64_t updates() const noexcept { return updates_; }
  uint64_t unsettled_updates() const noexcept { return unsettled_; }
  uint64_t results_held() const noexcept { return held_; }

 private:
  std::chrono::milliseconds period_, max_age_;
  Clock::time_point last_update_, last_results_;
  uint64_t updates_ = 0, unsettled_ = 0, held_ = 0;
};

// Paces each robot's results so that the poses the central converts, serialises and sends per robot
// stay within a rate: a result of n poses makes that robot's next one wait n / rate seconds. Results
// of updates that come sooner stay pending and go out, as the newest estimate, when the robot's turn
// comes, so a long mission's growing trajectories cost a bounded amount of work per second.
class ResultPacer {
 public:
  using Clock = UpdateSchedule::Clock;

  // poses_per_second <= 0: no pacing (every update's results go out at once).
  ResultPacer(size_t robots, double poses_per_second);

  // Every robot has new results.
  void updated();
  // The robot's new results are pending and its turn has come.
  bool due(uint32_t robot, Clock::time_point now) const;
  // Its results went out with this many poses (0: it had nothing to send).
  void sent(uint32_t robot, size_t poses, Clock::time_point now);
  // Updates whose results were folded into a later one for a robot, over all robots.
  uint64_t merged() const noexcept { return merged_; }

 private:
  struct Turn {
    bool pending = false;
    Clock::time_point next;
  };
  std::vector<Turn> turns_;
  double rate_;
  uint64_t merged_ = 0;
};

}  // namespace cdc::central
