// Radio faults of a launched swarm (netns mode): datagram loss, one-way cuts, flapping links and
// partitions, laid over the dataset's range periods for a window of sim time each.
//
// Windows are in sim time (when in the mission); a flapping link's period is in wall time, the
// clock of the DDS leases and dwell times it tests (lock-step playback runs slower than real time).
//
// A fault acts on directed pairs of nodes (robot ids and kCentralNode): every SLAM-domain datagram
// from `src` to `dst` is dropped with a probability. Faults that act on the same pair at once
// combine as independent losses, 1 - (1 - p1)(1 - p2). The launcher turns each directed pair's
// probability into one iptables rule (the `statistic` match for 0 < p < 1, a plain DROP for p = 1).
#pragma once

#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace cdc::launch {

enum class FaultKind {
  kLoss,       // random loss with `probability` on `between` (both ways) or, without it, every link
  kOneWay,     // `from` -> `to` cut; the other direction passes
  kFlap,       // `between` cut and restored, each state lasting period_s / 2 of wall time
  kPartition,  // every link between two different groups cut
};

struct RadioFault {
  FaultKind kind = FaultKind::kLoss;
  double from_s = 0;                                      // sim time the fault starts [s]
  double to_s = std::numeric_limits<double>::infinity();  // and ends (exclusive) [s]
  double probability = 0;                                 // kLoss
  std::vector<uint32_t> between;                          // kLoss (optional), kFlap: two nodes
  uint32_t from = 0, to = 0;                              // kOneWay
  double period_s = 2.0;                                  // kFlap: one cut plus one restore [wall s]
  std::vector<std::vector<uint32_t>> groups;              // kPartition: two or more disjoint groups
};

using DirectedPair = std::pair<uint32_t, uint32_t>;  // (src, dst)

// Reads the swarm file's `radio_faults` sequence. Nodes are robot ids or `central`. Every problem
// is appended to `errors` as "radio_faults[i]: ..."; the faults read without error are returned.
std::vector<RadioFault> parse_radio_faults(const YAML::Node& list, std::vector<std::string>& errors);

// The faults over a run: which directed pairs drop what, asked at increasing times.
class FaultSchedule {
 public:
  FaultSchedule(std::vector<RadioFault> faults, std::vector<uint32_t> nodes)
      : faults_(std::move(faults)), nodes_(std::move(nodes)), started_wall_s_(faults_.size(), -1.0) {}
  // Drop probability per directed pair at sim time sim_s and wall time wall_s [s]; pairs without a
  // fault are absent.
  std::map<DirectedPair, double> drops(double sim_s, double wall_s);
  bool empty() const { return faults_.empty(); }

 private:
  std::vector<RadioFault> faults_;
  std::vector<uint32_t> nodes_;
  std::vector<double> started_wall_s_;  // per fault: wall time its window opened (-1: not yet, or closed)
};

const char* to_string(FaultKind k);

}  // namespace cdc::launch
