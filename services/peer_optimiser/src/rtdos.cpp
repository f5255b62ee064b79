#include "cdc/peer_optimiser/rtdos.hpp"

#include "cdc/base/names.hpp"

#include <algorithm>
#include <array>

namespace cdc::peer {
namespace {

constexpr std::array<base::Named<SwitchReason>, 4> kSwitchReasonNames{
    {{SwitchReason::kStartup, "startup"},
     {SwitchReason::kLivelinessLost, "liveliness lost"},
     {SwitchReason::kOutOfRange, "out of range"},
     {SwitchReason::kBackInRange, "back in range"}}};

}  // namespace

const char* to_string(Mode mode) noexcept { return mode == Mode::kCentralized ? "CENTRALIZED" : "DISTRIBUTED"; }

const char* to_string(SwitchReason reason) noexcept { return base::name_of(kSwitchReasonNames, reason, "?"); }

Rtdos::Rtdos(const RtdosParams& params, Nanos start) : params_(params), last_switch_(start) {}

Transition Rtdos::switch_to(Mode to, SwitchReason why, const RtdosInput& in) {
  Transition t{mode_, to, why, in.now, in.distance_m};
  if (to == Mode::kDistributed) {
    // The first join (transition 1) follows start-up, not a stint away: no flap.
    const bool flap =
        last_reason_ == SwitchReason::kBackInRange && transitions_ >= 2 && in.now - last_switch_ < params_.flap_window;
    dwell_factor_ = flap ? std::min(2 * dwell_factor_, std::max<uint32_t>(params_.max_dwell_factor, 1)) : 1;
  }
  mode_ = to;
  last_reason_ = why;
  last_switch_ = in.now;
  in_range_since_.reset();
  ++transitions_;
  return t;
}

std::optional<Transition> Rtdos::update(const RtdosInput& in) {
  const bool masked = in.now - last_switch_ < params_.mask;
  if (mode_ == Mode::kCentralized) {
    if (!in.central_alive) {
      return switch_to(Mode::kDistributed, SwitchReason::kLivelinessLost, in);  // never masked
    }
    if (!masked && in.distance_m && *in.distance_m > params_.range_m) {
      return switch_to(Mode::kDistributed, SwitchReason::kOutOfRange, in);
    }
    return std::nullopt;
  }
  // DISTRIBUTED: return only after a continuous dwell in range with the central alive.
  const bool in_range = !in.distance_m || *in.distance_m < params_.range_m - params_.hysteresis_m;
  if (!in.central_alive || !in_range) {
    in_range_since_.reset();
    return std::nullopt;
  }
  if (!in_range_since_) {
    in_range_since_ = in.now;
  }
  if (!masked && in.now - *in_range_since_ >= dwell()) {
    return switch_to(Mode::kCentralized, SwitchReason::kBackInRange, in);
  }
  return std::nullopt;
}

}  // namespace cdc::peer
