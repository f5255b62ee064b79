// What the central has not acknowledged of this robot's keyframes and own loop closures, and when
// to send it again. The central acknowledges the highest id up to which it holds every keyframe
// (and loop seq) of the robot's current incarnation; anything above that goes again at once on a
// rejoin, and while CENTRALIZED once it has waited `resend_grace` unacknowledged. At most
// `max_resend_per_step` of each go per step, one step per `resend_period`, so that a long backlog
// goes out over several periods; what is sent waits `resend_grace` again.
#pragma once

#include "cdc/peer_optimiser/peer_types.hpp"

#include <cstdint>
#include <map>
#include <vector>

namespace cdc::peer {

class CentralBacklog {
 public:
  struct Resend {
    std::vector<uint32_t> keyframes;
    std::vector<uint32_t> loops;  // own loop seqs
  };

  explicit CentralBacklog(const PeerConfig& config) : config_(config) {}

  // A new own keyframe or own loop closure, sent (by the front-end or the loop service) at `now`.
  void add_keyframe(uint32_t id, Nanos now) { keyframe_sent_[id] = now; }
  void add_own_loop(uint32_t seq, Nanos now) { loop_sent_[seq] = now; }
  // The central's acknowledgement (of this robot's current incarnation).
  void on_ack(const AckIn& a) { ack_ = a; }
  // A new central incarnation: it holds nothing yet.
  void forget_acknowledgements(uint32_t central_incarnation) { ack_ = AckIn{central_incarnation, 0, -1, -1}; }
  // The robot rejoins the central: the next resend sends everything unacknowledged.
  void on_rejoin() { rejoining_ = true; }
  // What to send again now, called at every CENTRALIZED step.
  Resend due(Nanos now, bool central_alive);

  int64_t acknowledged_keyframe() const noexcept { return ack_.keyframe; }

 private:
  void pick(std::map<uint32_t, Nanos>& sent_at, int64_t acknowledged, Nanos now, std::vector<uint32_t>& resend) const;

  PeerConfig config_;
  std::map<uint32_t, Nanos> keyframe_sent_;  // own keyframe id -> last (re)sent
  std::map<uint32_t, Nanos> loop_sent_;      // own loop seq -> last (re)sent
  AckIn ack_;
  bool rejoining_ = false;
  Nanos last_resend_{0};
};

}  // namespace cdc::peer
