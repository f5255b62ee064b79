#include "peer_traffic.hpp"

namespace cdc::loops {

std::map<std::string, PeerBytes> PeerTraffic::by_peer() const {
  std::map<std::string, PeerBytes> out;
  for (const auto& [peer, bytes] : peers_) out[std::to_string(peer)] = bytes;
  return out;
}

}  // namespace cdc::loops
