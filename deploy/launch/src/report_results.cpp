#include "report_results.hpp"

#include "cdc/graph/g2o.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>
#include <tuple>

namespace cdc::launch {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kRobotServices[] = {"frontend", "descriptor", "loop_closure", "peer_optimiser"};

fs::path robot_dir(const fs::path& parent, uint32_t robot) { return parent / ("robot_" + std::to_string(robot)); }

std::optional<double> per(uint64_t amount, uint64_t count) {
  if (count == 0) return std::nullopt;
  return static_cast<double>(amount) / static_cast<double>(count);
}

std::vector<Transition> read_modes(const fs::path& p) {
  std::vector<Transition> out;
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string x;
    while (std::getline(ss, x, ',')) f.push_back(x);
    if (f.size() < 6) continue;
    try {
      out.push_back({std::stoll(f[0]), std::stoll(f[1]), f[3], f[4], f[5]});
    } catch (const std::exception&) {
      continue;  // a line cut short by a killed process
    }
  }
  return out;
}

// Position of the ground truth at the stamp nearest to t.
Eigen::Vector3d gt_position(const geometry::Trajectory& gt, int64_t t) {
  auto it = std::lower_bound(gt.begin(), gt.end(), t,
                             [](const geometry::StampedPose& p, int64_t v) { return p.stamp_ns < v; });
  if (it == gt.end()) return gt.back().pose.translation();
  if (it != gt.begin() && std::abs(std::prev(it)->stamp_ns - t) < std::abs(it->stamp_ns - t)) --it;
  return it->pose.translation();
}

// The robot's keyframes in the central's graph (when it holds them), and every trajectory in KITTI format too.
void write_trajectory_files(const fs::path& rd, const geometry::Trajectory* central) {
  if (central) geometry::write_tum((rd / "keyframes_central.tum").string(), *central);
  for (const char* name : {"odometry", "keyframes", "keyframes_central"}) {
    const fs::path tum = rd / (std::string(name) + ".tum");
    if (fs::exists(tum))
      geometry::write_kitti((rd / (std::string(name) + ".kitti")).string(), geometry::read_tum(tum.string()));
  }
}

TrajectoryResult evaluate_trajectory(const fs::path& tum, const geometry::Trajectory& gt, const std::string& name,
                                     const eval::EvalOptions& options) {
  TrajectoryResult out;
  if (!fs::exists(tum)) {
    out.error = "no trajectory written";
    return out;
  }
  const geometry::Trajectory est = geometry::read_tum(tum.string());
  if (gt.size() < 2 || est.size() < 2) {
    out.error = "too few poses";
    out.poses = est.size();
    return out;
  }
  try {
    out.evaluation = eval::evaluate(name, est, gt, options);
  } catch (const std::exception& ex) {
    out.error = ex.what();
  }
  return out;
}

ModeSwitches count_switches(const std::vector<Transition>& transitions) {
  ModeSwitches s;
  for (const Transition& t : transitions) {
    if (t.to == "DISTRIBUTED") ++s.to_distributed;
    if (t.to == "CENTRALIZED") ++s.to_centralized;
    if (t.reason.find("liveliness") != std::string::npos) ++s.on_liveliness_lost;
  }
  return s;
}

// A triangle where the robot switched to DISTRIBUTED, a circle where it came back, on its ground truth
// at the switch's sim time (not the start-up transition before the first sweep).
std::vector<eval::SvgMarker> switch_markers(const std::vector<Transition>& transitions, const geometry::Trajectory& gt,
                                            size_t index) {
  std::vector<eval::SvgMarker> out;
  if (gt.empty()) return out;
  for (const Transition& t : transitions) {
    if (t.sim_ns <= 0) continue;
    eval::SvgMarker m;
    m.position = gt_position(gt, t.sim_ns);
    m.triangle = t.to == "DISTRIBUTED";
    m.color = eval::plot_color(index);
    m.label = (t.to == "DISTRIBUTED" ? "D " : "C ") + fixed(static_cast<double>(t.sim_ns) * 1e-9, 0) + " s";
    out.push_back(m);
  }
  return out;
}

json read_service_stats(const fs::path& rd) {
  json stats;
  for (const char* svc : kRobotServices) {
    const fs::path sp = rd / (std::string(svc) + ".stats.json");
    if (!fs::exists(sp)) continue;
    try {
      std::ifstream in(sp);
      stats[svc] = json::parse(in);
    } catch (const std::exception&) {
      stats[svc] = {{"error", "unreadable"}};
    }
  }
  return stats;
}

uint64_t total_keyframes(const ModeTraffic& t) {
  uint64_t n = 0;
  for (const auto& [mode, k] : t.keyframes) n += k;
  return n;
}

// Keyframes made at both ends of a link while `t`'s robot was in `mode`: its own, and a robot peer's
// (the central makes none).
uint64_t keyframes_both_ends(const ModeTraffic& t, const std::string& mode, uint32_t peer) {
  uint64_t n = t.keyframes.count(mode) ? t.keyframes.at(mode) : 0;
  if (const auto m = t.peer_keyframes.find(mode); m != t.peer_keyframes.end()) {
    if (const auto p = m->second.find(peer); p != m->second.end()) n += p->second;
  }
  return n;
}

std::vector<LinkModeTraffic> link_mode_traffic(const RunInfo& info) {
  std::vector<LinkModeTraffic> out;
  for (const auto& [r, t] : info.traffic) {
    for (const auto& [mode, peers] : t.bytes) {
      const uint64_t own = t.keyframes.count(mode) ? t.keyframes.at(mode) : 0;
      for (const auto& [peer, b] : peers) out.push_back({r, peer, mode, b, own, keyframes_both_ends(t, mode, peer)});
    }
  }
  return out;
}

// Each robot pair once, as counted at the lower id.
std::map<std::string, RobotPairTraffic> robot_pairs_whole_run(const RunInfo& info) {
  std::map<std::string, RobotPairTraffic> out;
  for (const auto& [r, t] : info.traffic) {
    std::map<uint32_t, uint64_t> bytes;
    for (const auto& [mode, peers] : t.bytes) {
      for (const auto& [peer, b] : peers) bytes[peer] += b.sent + b.received;
    }
    for (const auto& [peer, total] : bytes) {
      if (peer == kCentralNode || peer <= r) continue;
      const auto pt = info.traffic.find(peer);
      const uint64_t kf_peer = pt != info.traffic.end() ? total_keyframes(pt->second) : 0;
      out[node_name(r) + "-" + node_name(peer)] = {total, total_keyframes(t) + kf_peer};
    }
  }
  return out;
}

}  // namespace

double TrajectoryResult::ate_pct_of_length() const {
  const eval::Evaluation& e = *evaluation;
  return e.gt_length_m > 0 ? 100.0 * e.ate.translation.rmse / e.gt_length_m : 0.0;
}

json TrajectoryResult::to_json(const eval::EvalOptions& options) const {
  if (!evaluation) {
    json j{{"error", error}};
    if (poses) j["poses"] = *poses;
    return j;
  }
  json j = eval::to_json(*evaluation, options);
  j["ate_pct_of_length"] = ate_pct_of_length();
  return j;
}

json RobotResult::to_json(const eval::EvalOptions& options) const {
  json j;
  j["keyframes_source"] = keyframes_from_central ? "central's final graph" : "peer optimiser";
  j["odometry"] = odometry.to_json(options);
  j["keyframes"] = keyframes.to_json(options);
  json jt = json::array();
  for (const Transition& t : transitions) {
    jt.push_back(
        {{"sim_s", static_cast<double>(t.sim_ns) * 1e-9}, {"from", t.from}, {"to", t.to}, {"reason", t.reason}});
  }
  j["transitions"] = jt;
  j["switches_to_distributed"] = switches.to_distributed;
  j["switches_to_centralized"] = switches.to_centralized;
  j["switches_on_liveliness_lost"] = switches.on_liveliness_lost;
  if (!stats.is_null()) j["stats"] = stats;
  return j;
}

// Keyframe ids from the graph's keys (robot << 56 | session << 32 | id), stamps from the robot's own
// keyframe list (the peer optimiser's keyframes.tum holds every keyframe, in id order).
std::map<uint32_t, geometry::Trajectory> central_trajectories(const fs::path& g2o, const fs::path& run,
                                                              const std::vector<uint32_t>& robots) {
  std::map<uint32_t, geometry::Trajectory> out;
  if (!fs::exists(g2o)) return out;
  graph::PoseGraph g;
  try {
    g = graph::read_g2o(g2o.string());
  } catch (const std::exception&) {
    return out;
  }
  for (uint32_t r : robots) {
    const fs::path kf = robot_dir(run, r) / "keyframes.tum";
    if (!fs::exists(kf)) continue;
    const geometry::Trajectory own = geometry::read_tum(kf.string());
    std::map<uint32_t, Eigen::Isometry3d> by_id;  // the latest session wins
    for (const auto& [key, T] : g.poses) {
      if (graph::robot_of(key) == r) by_id[static_cast<uint32_t>(key & 0xffffffffu)] = T;
    }
    geometry::Trajectory t;
    for (const auto& [id, T] : by_id) {
      if (id < own.size()) t.push_back({own[id].stamp_ns, T});
    }
    if (t.size() * 10 >= own.size() * 9) out[r] = std::move(t);  // the robot is (nearly) all there
  }
  return out;
}

RobotResult gather_robot(const RunInfo& info, uint32_t robot, size_t index,
                         const std::map<uint32_t, geometry::Trajectory>& central, const eval::EvalOptions& options) {
  const fs::path rd = robot_dir(info.run_dir, robot);
  const auto own_central = central.find(robot);
  RobotResult out;
  out.robot = robot;
  out.keyframes_from_central = own_central != central.end();
  write_trajectory_files(rd, out.keyframes_from_central ? &own_central->second : nullptr);
  const fs::path gt_path = robot_dir(info.dataset, robot) / "groundtruth.tum";
  geometry::Trajectory gt;
  if (fs::exists(gt_path)) gt = geometry::read_tum(gt_path.string());
  const std::string name = "robot " + std::to_string(robot);
  out.odometry = evaluate_trajectory(rd / "odometry.tum", gt, name + " odometry", options);
  out.keyframes = evaluate_trajectory(rd / (out.keyframes_from_central ? "keyframes_central.tum" : "keyframes.tum"), gt,
                                      name + " keyframes", options);
  out.transitions = read_modes(rd / "modes.csv");
  out.switches = count_switches(out.transitions);
  out.markers = switch_markers(out.transitions, gt, index);
  out.stats = read_service_stats(rd);
  return out;
}

std::optional<double> LinkModeTraffic::sent_per_keyframe() const { return per(bytes.sent, keyframes_in_mode); }

std::optional<double> LinkModeTraffic::bytes_per_keyframe() const {
  return per(bytes.sent + bytes.received, keyframes_in_mode);
}

std::optional<double> LinkModeTraffic::bytes_per_keyframe_both_ends() const {
  return per(bytes.sent + bytes.received, keyframes_both_ends);
}

json LinkModeTraffic::to_json() const {
  json l{{"sent_bytes", bytes.sent},
         {"received_bytes", bytes.received},
         {"discovery_sent_bytes", bytes.meta_sent},
         {"discovery_received_bytes", bytes.meta_received},
         {"keyframes_in_mode", keyframes_in_mode},
         {"keyframes_both_ends", keyframes_both_ends}};
  if (const auto b = bytes_per_keyframe()) l["bytes_per_keyframe"] = *b;
  if (const auto s = sent_per_keyframe()) l["sent_bytes_per_keyframe"] = *s;
  if (const auto b = bytes_per_keyframe_both_ends()) l["bytes_per_keyframe_both_ends"] = *b;
  return l;
}

std::optional<double> RobotPairTraffic::bytes_per_keyframe() const { return per(user_bytes, keyframes_both_ends); }

json RobotPairTraffic::to_json() const {
  json l{{"user_bytes", user_bytes}, {"keyframes_both_ends", keyframes_both_ends}};
  if (const auto b = bytes_per_keyframe()) l["bytes_per_keyframe"] = *b;
  return l;
}

json TrafficSummary::to_json() const {
  json per_link;
  for (const LinkModeTraffic& l : links) {
    json& m = per_link[node_name(l.robot) + "-" + node_name(l.peer)][l.mode];
    m["sent_bytes"] = l.bytes.sent;
    m["received_bytes"] = l.bytes.received;
    m["discovery_bytes"] = l.bytes.meta_sent + l.bytes.meta_received;
  }
  json whole = json::object();
  for (const auto& [link, p] : robot_links_whole_run) whole[link] = p.to_json();
  return {
      {"per_link", per_link},
      {"robot_links_whole_run", whole},
      {"max_robot_link_bytes_per_keyframe_whole_run", max_robot_link_bytes_per_keyframe_whole_run},
      {"max_distributed_bytes_per_keyframe_per_link", max_distributed_bytes_per_keyframe_per_link},
      {"max_distributed_sent_bytes_per_own_keyframe_per_link", max_distributed_sent_bytes_per_own_keyframe_per_link},
      {"max_distributed_bytes_per_keyframe_both_ends_per_link", max_distributed_bytes_per_keyframe_both_ends_per_link}};
}

json TrafficSummary::robot_json(uint32_t robot) const {
  json out;
  for (const LinkModeTraffic& l : links) {
    if (l.robot == robot) out[l.mode][node_name(l.peer)] = l.to_json();
  }
  return out;
}

TrafficSummary summarise_traffic(const RunInfo& info) {
  TrafficSummary s;
  s.links = link_mode_traffic(info);
  for (const LinkModeTraffic& l : s.links) {
    if (l.mode != "DISTRIBUTED") continue;
    s.max_distributed_bytes_per_keyframe_per_link =
        std::max(s.max_distributed_bytes_per_keyframe_per_link, l.bytes_per_keyframe().value_or(0.0));
    s.max_distributed_sent_bytes_per_own_keyframe_per_link =
        std::max(s.max_distributed_sent_bytes_per_own_keyframe_per_link, l.sent_per_keyframe().value_or(0.0));
    s.max_distributed_bytes_per_keyframe_both_ends_per_link = std::max(
        s.max_distributed_bytes_per_keyframe_both_ends_per_link, l.bytes_per_keyframe_both_ends().value_or(0.0));
  }
  s.robot_links_whole_run = robot_pairs_whole_run(info);
  for (const auto& [link, p] : s.robot_links_whole_run) {
    s.max_robot_link_bytes_per_keyframe_whole_run =
        std::max(s.max_robot_link_bytes_per_keyframe_whole_run, p.bytes_per_keyframe().value_or(0.0));
  }
  return s;
}

// The counters each service's DDS layer writes into its --stats-out file under "topics" (domain ->
// topic -> counters).
json topic_traffic(const fs::path& run, const std::vector<uint32_t>& robots) {
  std::vector<std::tuple<std::string, std::string, fs::path>> services;  // node, service, stats file
  for (uint32_t r : robots) {
    for (const char* svc : kRobotServices) {
      services.emplace_back(node_name(r), svc, robot_dir(run, r) / (std::string(svc) + ".stats.json"));
    }
  }
  services.emplace_back(node_name(kCentralNode), "central_optimiser", run / "central.stats.json");
  services.emplace_back(node_name(kCentralNode), "map", run / "map.stats.json");
  json out = json::object();
  for (const auto& [node, service, file] : services) {
    if (!fs::exists(file)) continue;
    try {
      std::ifstream in(file);
      const json stats = json::parse(in);
      if (stats.contains("topics") && stats["topics"].is_object()) out[node][service] = stats["topics"];
    } catch (const std::exception&) {
      // an unreadable stats file is reported with the robot's stats
    }
  }
  return out;
}

}  // namespace cdc::launch
