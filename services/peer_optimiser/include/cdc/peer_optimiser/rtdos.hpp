// RTDOS (range-triggered dual-optimisation switching, CDC-SLAM paper III-A-2): decides whether a
// robot's back-end is CENTRALIZED or DISTRIBUTED. Pure and synchronous: the caller feeds it the
// central optimiser's liveliness and the estimated distance to the central node with a time.
//
//  CENTRALIZED -> DISTRIBUTED  at once when the central's liveliness is lost (always), or when the
//                              distance exceeds CR_0 (a range trigger, blocked while the mask runs);
//  DISTRIBUTED -> CENTRALIZED  when the central is alive and the distance has stayed below
//                              CR_0 - hysteresis for the dwell time (also a range trigger).
// An unknown distance (no world pose yet) counts as in range: a live central is reachable.
// Flap damping: a link at the range edge can come and go faster than the lease lapses, so that the
// central stays alive through a dwell and is lost again just after the return. A return followed
// within flap_window by a switch away doubles the dwell for the next return (up to
// max_dwell_factor times); a CENTRALIZED stint longer than flap_window restores it. The first join
// after start-up is no return: losing the central right after it is no flap.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>

namespace cdc::peer {

using Nanos = std::chrono::nanoseconds;  // monotonic time since an arbitrary origin

enum class Mode { kCentralized, kDistributed };
enum class SwitchReason { kStartup, kLivelinessLost, kOutOfRange, kBackInRange };
const char* to_string(Mode mode) noexcept;
const char* to_string(SwitchReason reason) noexcept;

struct RtdosParams {
  double range_m = 100.0;                       // CR_0, the central node's communication range [m]
  double hysteresis_m = 10.0;                   // return only below CR_0 - hysteresis [m]
  Nanos dwell{std::chrono::seconds(3)};         // in range (and central alive) this long before returning
  Nanos mask{std::chrono::seconds(2)};          // after any switch, range triggers are ignored this long
  Nanos flap_window{std::chrono::seconds(10)};  // a return lost again within this is a flap
  uint32_t max_dwell_factor = 8;                // the dwell grows by flaps to at most this many times
};

struct RtdosInput {
  Nanos now{0};
  bool central_alive = false;
  std::optional<double> distance_m;  // to the central node, when a world pose is known
};

struct Transition {
  Mode from = Mode::kDistributed;
  Mode to = Mode::kDistributed;
  SwitchReason reason = SwitchReason::kStartup;
  Nanos when{0};
  std::optional<double> distance_m;
};

class Rtdos {
 public:
  explicit Rtdos(const RtdosParams& params, Nanos start = Nanos{0});

  // Feeds one observation; returns the transition it caused, if any. Times must not go back.
  std::optional<Transition> update(const RtdosInput& in);

  Mode mode() const noexcept { return mode_; }
  SwitchReason last_reason() const noexcept { return last_reason_; }
  uint32_t transitions() const noexcept { return transitions_; }
  const RtdosParams& params() const noexcept { return params_; }
  // The dwell the next return to CENTRALIZED waits for (the configured one times the flap factor).
  Nanos dwell() const noexcept { return params_.dwell * dwell_factor_; }

 private:
  Transition switch_to(Mode to, SwitchReason why, const RtdosInput& in);

  RtdosParams params_;
  Mode mode_ = Mode::kDistributed;  // no central known at start
  SwitchReason last_reason_ = SwitchReason::kStartup;
  Nanos last_switch_{0};
  std::optional<Nanos> in_range_since_;
  uint32_t transitions_ = 0;
  uint32_t dwell_factor_ = 1;
};

}  // namespace cdc::peer
