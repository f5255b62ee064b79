// The radio between the swarm's nodes: from true positions and each node's communication range, the
// state of every link over time (in range or not, distance, a loss probability rising near the edge).
#pragma once

#include <Eigen/Core>

#include <cstdint>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

namespace cdc::sim {

struct RadioNode {
  uint32_t id = 0;
  double range_m = 100;                             // communication range of this node
  std::function<Eigen::Vector3d(double)> position;  // true position at time t [s]
};

struct RadioOptions {
  double loss_start_fraction = 0.8;  // loss starts at this fraction of the link's range
  double max_loss = 0.3;             // loss probability at the edge of the range
  double period_s = 0.1;             // timeline resolution
  std::function<bool()> stop;        // asked at every step when set: true abandons the work (throws Stopped)
};

// Thrown by a long computation whose stop predicate asked it to end (a signal, in the tools).
class Stopped : public std::runtime_error {
 public:
  Stopped() : std::runtime_error("stopped on request") {}
};

struct LinkSample {
  double t = 0;
  uint32_t a = 0, b = 0;  // a < b
  bool in_range = false;
  double distance = 0;  // [m]
  double loss = 0;      // probability a datagram is lost
};

// Link states of every pair at every period over [t0, t1]. A link is in range when the distance is
// within the smaller of the two nodes' ranges.
std::vector<LinkSample> radio_timeline(const std::vector<RadioNode>& nodes, double t0, double t1,
                                       const RadioOptions& options);

struct OutOfRangePeriod {
  uint32_t a = 0, b = 0;
  double start = 0, end = 0;  // [s]
};

// Maximal out-of-range intervals per pair.
std::vector<OutOfRangePeriod> out_of_range_periods(const std::vector<LinkSample>& timeline);

// CSV "t,a,b,in_range,distance,loss" with a header, fixed formatting (byte-identical for the same input).
std::string radio_csv(const std::vector<LinkSample>& timeline);

}  // namespace cdc::sim
