// Bytes the loop-closure service exchanged with each peer robot (the serialised size of its samples),
// for --stats-out's "bytes_per_peer". The DDS layer counts the totals per topic (cdc/dds/traffic.hpp);
// only the node knows which robot a sample came from or went to. No DDS.
#pragma once

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>

namespace cdc::loops {

struct PeerBytes {
  uint64_t sent = 0, received = 0;
};
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(PeerBytes, sent, received)

class PeerTraffic {
 public:
  void sent(uint32_t peer, size_t bytes) { peers_[peer].sent += bytes; }
  void received(uint32_t peer, size_t bytes) { peers_[peer].received += bytes; }

  // Every peer that traffic went to or came from, keyed by its id in decimal (the stats file's keys).
  std::map<std::string, PeerBytes> by_peer() const;

 private:
  std::map<uint32_t, PeerBytes> peers_;
};

}  // namespace cdc::loops
