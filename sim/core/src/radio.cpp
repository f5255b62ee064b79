#include "cdc/sim/radio.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

namespace cdc::sim {

std::vector<LinkSample> radio_timeline(const std::vector<RadioNode>& nodes, double t0, double t1,
                                       const RadioOptions& o) {
  std::vector<LinkSample> out;
  const auto steps = static_cast<int64_t>(std::floor((t1 - t0) / o.period_s + 1e-9));
  for (int64_t k = 0; k <= steps; ++k) {
    if (o.stop && o.stop()) throw Stopped();
    const double t = t0 + static_cast<double>(k) * o.period_s;
    std::vector<Eigen::Vector3d> p;
    p.reserve(nodes.size());
    for (const auto& n : nodes) {
      p.push_back(n.position(t));
    }
    for (size_t i = 0; i < nodes.size(); ++i) {
      for (size_t j = i + 1; j < nodes.size(); ++j) {
        LinkSample s;
        s.t = t;
        s.a = std::min(nodes[i].id, nodes[j].id);
        s.b = std::max(nodes[i].id, nodes[j].id);
        s.distance = (p[i] - p[j]).norm();
        const double range = std::min(nodes[i].range_m, nodes[j].range_m);
        s.in_range = s.distance <= range;
        const double start = o.loss_start_fraction * range;
        s.loss = s.in_range ? (s.distance <= start ? 0.0 : o.max_loss * (s.distance - start) / (range - start)) : 1.0;
        out.push_back(s);
      }
    }
  }
  return out;
}

std::vector<OutOfRangePeriod> out_of_range_periods(const std::vector<LinkSample>& timeline) {
  std::map<std::pair<uint32_t, uint32_t>, std::vector<const LinkSample*>> per_pair;
  for (const auto& s : timeline) {
    per_pair[{s.a, s.b}].push_back(&s);
  }
  std::vector<OutOfRangePeriod> out;
  for (const auto& [pair, samples] : per_pair) {
    bool open = false;
    OutOfRangePeriod cur;
    for (const LinkSample* s : samples) {
      if (!s->in_range && !open) {
        cur = OutOfRangePeriod{pair.first, pair.second, s->t, s->t};
        open = true;
      } else if (s->in_range && open) {
        cur.end = s->t;
        out.push_back(cur);
        open = false;
      }
    }
    if (open) {
      cur.end = samples.back()->t;
      out.push_back(cur);
    }
  }
  return out;
}

std::string radio_csv(const std::vector<LinkSample>& timeline) {
  std::string out = "t,a,b,in_range,distance,loss\n";
  char line[128];
  for (const auto& s : timeline) {
    std::snprintf(line, sizeof line, "%.3f,%u,%u,%d,%.3f,%.4f\n", s.t, s.a, s.b, s.in_range ? 1 : 0, s.distance,
                  s.loss);
    out += line;
  }
  return out;
}

}  // namespace cdc::sim
