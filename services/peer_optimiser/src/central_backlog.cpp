#include "cdc/peer_optimiser/central_backlog.hpp"

namespace cdc::peer {

CentralBacklog::Resend CentralBacklog::due(Nanos now, bool central_alive) {
  Resend r;
  if (!central_alive || (!rejoining_ && now - last_resend_ < config_.resend_period)) {
    return r;
  }
  pick(keyframe_sent_, ack_.keyframe, now, r.keyframes);
  pick(loop_sent_, ack_.loop_seq, now, r.loops);
  rejoining_ = false;
  last_resend_ = now;
  return r;
}

void CentralBacklog::pick(std::map<uint32_t, Nanos>& sent_at, int64_t acknowledged, Nanos now,
                          std::vector<uint32_t>& resend) const {
  for (auto& [id, sent] : sent_at) {
    if (resend.size() >= config_.max_resend_per_step) break;
    if (static_cast<int64_t>(id) > acknowledged && (rejoining_ || now - sent >= config_.resend_grace)) {
      resend.push_back(id);
      sent = now;
    }
  }
}

}  // namespace cdc::peer
