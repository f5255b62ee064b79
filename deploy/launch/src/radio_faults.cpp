#include "radio_faults.hpp"

#include "network.hpp"

#include "cdc/base/names.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <optional>
#include <set>
#include <stdexcept>

namespace cdc::launch {
namespace {

constexpr std::array<base::Named<FaultKind>, 4> kKindNames{{{FaultKind::kLoss, "loss"},
                                                            {FaultKind::kOneWay, "one_way"},
                                                            {FaultKind::kFlap, "flap"},
                                                            {FaultKind::kPartition, "partition"}}};

// Keys each kind accepts besides kind, from_s and to_s.
const std::map<FaultKind, std::set<std::string>> kKeys{{FaultKind::kLoss, {"probability", "between"}},
                                                       {FaultKind::kOneWay, {"from", "to"}},
                                                       {FaultKind::kFlap, {"between", "period_s"}},
                                                       {FaultKind::kPartition, {"groups"}}};

// Reading one fault: the first problem found throws std::invalid_argument with its reason.
uint32_t read_node(const YAML::Node& n, const std::string& key) {
  if (n.IsScalar() && n.Scalar() == "central") return kCentralNode;
  uint32_t id = 0;
  try {
    id = n.as<uint32_t>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument(key + ": '" + YAML::Dump(n) + "' is not a robot id or 'central'");
  }
  if (id >= 90) throw std::invalid_argument(key + ": robot id " + std::to_string(id) + " is not below 90");
  return id;
}

std::vector<uint32_t> read_nodes(const YAML::Node& n, const std::string& key) {
  if (!n.IsSequence()) throw std::invalid_argument(key + ": expected a list of nodes");
  std::vector<uint32_t> out;
  for (const YAML::Node& e : n) out.push_back(read_node(e, key));
  if (std::set<uint32_t>(out.begin(), out.end()).size() != out.size())
    throw std::invalid_argument(key + ": a node is named twice");
  return out;
}

double read_number(const YAML::Node& n, const std::string& key, double lo, double hi) {
  double v = 0;
  try {
    v = n.as<double>();
  } catch (const YAML::Exception&) {
    throw std::invalid_argument(key + ": '" + YAML::Dump(n) + "' is not a number");
  }
  if (!std::isfinite(v) || v < lo || v > hi) {
    throw std::invalid_argument(key + ": " + YAML::Dump(n) + " is outside [" + YAML::Dump(YAML::Node(lo)) + ", " +
                                YAML::Dump(YAML::Node(hi)) + "]");
  }
  return v;
}

FaultKind read_kind(const YAML::Node& item) {
  if (!item.IsMap()) throw std::invalid_argument("expected a map with a 'kind'");
  const YAML::Node k = item["kind"];
  const std::optional<FaultKind> kind = k && k.IsScalar() ? base::value_of(kKindNames, k.Scalar()) : std::nullopt;
  if (!kind) throw std::invalid_argument("kind: expected " + base::names_list(kKindNames));
  return *kind;
}

void read_window(const YAML::Node& item, RadioFault& f) {
  constexpr double kDay = 86400.0;
  if (item["from_s"]) f.from_s = read_number(item["from_s"], "from_s", 0, kDay);
  if (item["to_s"]) f.to_s = read_number(item["to_s"], "to_s", 0, kDay);
  if (f.to_s <= f.from_s) throw std::invalid_argument("to_s must be after from_s");
}

void read_kind_fields(const YAML::Node& item, RadioFault& f) {
  switch (f.kind) {
    case FaultKind::kLoss:
      if (!item["probability"]) throw std::invalid_argument("probability: required");
      f.probability = read_number(item["probability"], "probability", 0, 1);
      if (item["between"]) f.between = read_nodes(item["between"], "between");
      break;
    case FaultKind::kOneWay:
      if (!item["from"] || !item["to"]) throw std::invalid_argument("from and to: required");
      f.from = read_node(item["from"], "from");
      f.to = read_node(item["to"], "to");
      if (f.from == f.to) throw std::invalid_argument("from and to name the same node");
      break;
    case FaultKind::kFlap:
      if (!item["between"]) throw std::invalid_argument("between: required");
      f.between = read_nodes(item["between"], "between");
      if (item["period_s"]) f.period_s = read_number(item["period_s"], "period_s", 0.1, 3600);
      break;
    case FaultKind::kPartition: {
      const YAML::Node g = item["groups"];
      if (!g || !g.IsSequence() || g.size() < 2) throw std::invalid_argument("groups: expected two or more lists");
      std::set<uint32_t> seen;
      for (const YAML::Node& group : g) {
        f.groups.push_back(read_nodes(group, "groups"));
        for (uint32_t n : f.groups.back()) {
          if (!seen.insert(n).second) throw std::invalid_argument("groups: node " + std::to_string(n) + " twice");
        }
      }
      break;
    }
  }
  if (!f.between.empty() && f.between.size() != 2) throw std::invalid_argument("between: expected two nodes");
}

RadioFault read_fault(const YAML::Node& item) {
  RadioFault f;
  f.kind = read_kind(item);
  for (const auto& kv : item) {
    const std::string key = kv.first.as<std::string>();
    if (key != "kind" && key != "from_s" && key != "to_s" && !kKeys.at(f.kind).count(key))
      throw std::invalid_argument(key + ": not a key of a " + to_string(f.kind) + " fault");
  }
  read_window(item, f);
  read_kind_fields(item, f);
  return f;
}

bool on_link(const std::vector<uint32_t>& between, uint32_t a, uint32_t b) {
  return (between[0] == a && between[1] == b) || (between[0] == b && between[1] == a);
}

int group_of(const std::vector<std::vector<uint32_t>>& groups, uint32_t n) {
  for (size_t i = 0; i < groups.size(); ++i) {
    if (std::find(groups[i].begin(), groups[i].end(), n) != groups[i].end()) return static_cast<int>(i);
  }
  return -1;
}

// What one active fault drops from src to dst, `wall_s` into its window.
double drop(const RadioFault& f, uint32_t src, uint32_t dst, double wall_s) {
  switch (f.kind) {
    case FaultKind::kLoss:
      return f.between.empty() || on_link(f.between, src, dst) ? f.probability : 0.0;
    case FaultKind::kOneWay:
      return f.from == src && f.to == dst ? 1.0 : 0.0;
    case FaultKind::kFlap: {
      // Cut in the first half of every period, restored in the second.
      const double phase = std::fmod(wall_s, f.period_s);
      return on_link(f.between, src, dst) && phase < 0.5 * f.period_s ? 1.0 : 0.0;
    }
    case FaultKind::kPartition: {
      const int gs = group_of(f.groups, src), gd = group_of(f.groups, dst);
      return gs >= 0 && gd >= 0 && gs != gd ? 1.0 : 0.0;
    }
  }
  return 0.0;
}

}  // namespace

const char* to_string(FaultKind k) { return base::name_of(kKindNames, k, "?"); }

std::vector<RadioFault> parse_radio_faults(const YAML::Node& list, std::vector<std::string>& errors) {
  std::vector<RadioFault> out;
  if (!list || list.IsNull()) return out;
  if (!list.IsSequence()) {
    errors.push_back("radio_faults: expected a list of faults");
    return out;
  }
  for (size_t i = 0; i < list.size(); ++i) {
    try {
      out.push_back(read_fault(list[i]));
    } catch (const std::exception& e) {
      errors.push_back("radio_faults[" + std::to_string(i) + "]: " + e.what());
    }
  }
  return out;
}

std::map<DirectedPair, double> FaultSchedule::drops(double sim_s, double wall_s) {
  std::vector<double> into(faults_.size(), -1.0);  // wall seconds into each active fault's window
  for (size_t i = 0; i < faults_.size(); ++i) {
    if (sim_s < faults_[i].from_s || sim_s >= faults_[i].to_s) {
      started_wall_s_[i] = -1.0;
      continue;
    }
    if (started_wall_s_[i] < 0) started_wall_s_[i] = wall_s;
    into[i] = wall_s - started_wall_s_[i];
  }
  std::map<DirectedPair, double> out;
  for (uint32_t src : nodes_) {
    for (uint32_t dst : nodes_) {
      if (src == dst) continue;
      double pass = 1.0;
      for (size_t i = 0; i < faults_.size(); ++i) {
        if (into[i] >= 0) pass *= 1.0 - drop(faults_[i], src, dst, into[i]);
      }
      if (pass < 1.0) out[{src, dst}] = 1.0 - pass;
    }
  }
  return out;
}

}  // namespace cdc::launch
