#include "report.hpp"

#include "process.hpp"

#include "cdc/eval/evaluation.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/trajectory.hpp"
#include "cdc/graph/g2o.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <tuple>
#include <sstream>

namespace cdc::launch {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Keyframes made at both ends of a link while `t`'s robot was in `mode`: its own, and a robot peer's
// (the central makes none).
uint64_t keyframes_both_ends(const ModeTraffic& t, const std::string& mode, uint32_t peer) {
  uint64_t n = t.keyframes.count(mode) ? t.keyframes.at(mode) : 0;
  if (const auto m = t.peer_keyframes.find(mode); m != t.peer_keyframes.end()) {
    if (const auto p = m->second.find(peer); p != m->second.end()) n += p->second;
  }
  return n;
}

struct Transition {
  int64_t wall_ns = 0, sim_ns = 0;
  std::string from, to, reason;
};

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
  auto it = std::lower_bound(gt.begin(), gt.end(), t, [](const geometry::StampedPose& p, int64_t v) { return p.stamp_ns < v; });
  if (it == gt.end()) return gt.back().pose.translation();
  if (it != gt.begin() && std::abs(std::prev(it)->stamp_ns - t) < std::abs(it->stamp_ns - t)) --it;
  return it->pose.translation();
}

// The central's final graph (after its last full optimisation) as one trajectory per robot:
// keyframe ids from the keys (robot << 56 | session << 32 | id), stamps from the robot's own
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
    const fs::path kf = run / ("robot_" + std::to_string(r)) / "keyframes.tum";
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


// Mode over sim time, one row per robot, with the periods its link to the central was cut.
std::string render_timeline(const RunInfo& info, const std::map<uint32_t, std::vector<Transition>>& modes) {
  const double w = 900, left = 90, right = 20, row = 46, top = 50;
  const double h = top + row * static_cast<double>(info.robots.size()) + 60;
  const double t_end = std::max(info.sim_end_s, 1.0);
  auto px = [&](double t) { return left + (w - left - right) * std::clamp(t / t_end, 0.0, 1.0); };
  std::ostringstream s;
  s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << w << "\" height=\"" << h
    << "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
    << "<text x=\"" << left << "\" y=\"24\" font-size=\"15\">" << info.name << ": back-end mode over sim time</text>\n";
  double y = top;
  for (uint32_t r : info.robots) {
    s << "<text x=\"10\" y=\"" << y + 16 << "\">robot " << r << "</text>\n";
    std::string mode = info.central ? "CENTRALIZED" : "DISTRIBUTED";
    double t0 = 0;
    auto bar = [&](double a, double b, const std::string& m) {
      s << "<rect x=\"" << fixed(px(a), 1) << "\" y=\"" << y << "\" width=\"" << fixed(std::max(px(b) - px(a), 0.5), 1)
        << "\" height=\"22\" fill=\"" << (m == "CENTRALIZED" ? "#1f77b4" : "#ff7f0e") << "\"/>\n";
    };
    auto it = modes.find(r);
    if (it != modes.end()) {
      for (const Transition& t : it->second) {
        const double ts = static_cast<double>(t.sim_ns) * 1e-9;
        bar(t0, ts, mode);
        mode = t.to;
        t0 = ts;
      }
    }
    bar(t0, t_end, mode);
    // Link to the central cut (grey) under the bar.
    double cut_start = -1;  // < 0: the link is up
    auto cut_bar = [&](double a, double b) {
      s << "<rect x=\"" << fixed(px(a), 1) << "\" y=\"" << y + 25 << "\" width=\"" << fixed(std::max(px(b) - px(a), 0.5), 1)
        << "\" height=\"6\" fill=\"#777777\"/>\n";
    };
    for (const LinkEvent& e : info.links) {
      if (!((e.a == r && e.b == kCentralNode) || (e.b == r && e.a == kCentralNode))) continue;
      if (!e.up && cut_start < 0) cut_start = e.sim_s;
      if (e.up && cut_start >= 0) {
        cut_bar(cut_start, e.sim_s);
        cut_start = -1;
      }
    }
    if (cut_start >= 0) cut_bar(cut_start, t_end);
    y += row;
  }
  // Time axis.
  s << "<line x1=\"" << left << "\" y1=\"" << y << "\" x2=\"" << w - right << "\" y2=\"" << y << "\" stroke=\"black\"/>\n";
  const double step = t_end > 200 ? 50 : t_end > 50 ? 10 : 5;
  for (double t = 0; t <= t_end + 1e-9; t += step) {
    s << "<line x1=\"" << fixed(px(t), 1) << "\" y1=\"" << y << "\" x2=\"" << fixed(px(t), 1) << "\" y2=\"" << y + 5
      << "\" stroke=\"black\"/><text x=\"" << fixed(px(t) - 8, 1) << "\" y=\"" << y + 18 << "\">" << fixed(t, 0) << "</text>\n";
  }
  s << "<text x=\"" << w - right - 60 << "\" y=\"" << y + 34 << "\">sim time [s]</text>\n"
    << "<rect x=\"" << left << "\" y=\"" << y + 26 << "\" width=\"12\" height=\"10\" fill=\"#1f77b4\"/><text x=\"" << left + 16
    << "\" y=\"" << y + 35 << "\">CENTRALIZED</text>"
    << "<rect x=\"" << left + 120 << "\" y=\"" << y + 26 << "\" width=\"12\" height=\"10\" fill=\"#ff7f0e\"/><text x=\""
    << left + 136 << "\" y=\"" << y + 35 << "\">DISTRIBUTED</text>"
    << "<rect x=\"" << left + 240 << "\" y=\"" << y + 29 << "\" width=\"12\" height=\"5\" fill=\"#777777\"/><text x=\""
    << left + 256 << "\" y=\"" << y + 35 << "\">link to the central cut (emulated radio)</text>\n</svg>\n";
  return s.str();
}

void write_png(const fs::path& svg) {
  fs::path png = svg;
  png.replace_extension(".png");
  run_command({"rsvg-convert", "-o", png.string(), svg.string()});  // optional: librsvg2-bin
}

}  // namespace

std::string node_name(uint32_t n) {
  if (n == kCentralNode) return "central";
  return "robot" + std::to_string(n);
}

std::string fixed(double v, int decimals) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(decimals);
  s << v;
  return s.str();
}

// Per-topic payload of every service, from its --stats-out file ("topics": domain -> topic ->
// counters, written by the DDS layer): node -> service -> domain -> topic -> counters.
json topic_traffic(const fs::path& run, const std::vector<uint32_t>& robots) {
  std::vector<std::tuple<std::string, std::string, fs::path>> services;  // node, service, stats file
  for (uint32_t r : robots) {
    const fs::path rd = run / ("robot_" + std::to_string(r));
    for (const char* svc : {"frontend", "descriptor", "loop_closure", "peer_optimiser"}) {
      services.emplace_back(node_name(r), svc, rd / (std::string(svc) + ".stats.json"));
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

json write_report(const RunInfo& info) {
  const fs::path run(info.run_dir), ds(info.dataset);
  json j;
  j["name"] = info.name;
  j["variant"] = info.variant;
  j["network"] = info.network;
  j["dataset"] = info.dataset;
  j["swarm_file"] = info.swarm_file;
  j["wall_s"] = info.wall_s;
  j["sim_s"] = info.sim_end_s;
  j["interrupted"] = info.interrupted;
  j["notes"] = info.notes;
  if (info.rendezvous_s) {
    j["rendezvous"] = {{"waited_s", *info.rendezvous_s}, {"not_rejoined", info.not_rejoined},
                       {"loop_closure_busy", info.loop_closure_busy}};
    if (info.caught_up_s) j["rendezvous"]["loop_closure_caught_up_s"] = *info.caught_up_s;
  }
  j["domains"] = {{"slam", info.slam_domain}, {"sim", info.sim_domain}};
  std::vector<eval::Evaluation> kf_evals;
  std::vector<eval::SvgMarker> markers;
  std::map<uint32_t, std::vector<Transition>> modes;
  eval::EvalOptions eo;
  std::ofstream all_modes(run / "modes.csv");
  all_modes << "robot,wall_ns,sim_ns,from,to,reason\n";
  // Final optimised keyframes: the central's final graph for the robots it holds, else the peer's.
  const auto central = central_trajectories(run / "global_graph.g2o", run, info.robots);
  size_t k = 0;
  for (uint32_t r : info.robots) {
    const fs::path rd = run / ("robot_" + std::to_string(r));
    if (central.count(r)) {
      geometry::write_tum((rd / "keyframes_central.tum").string(), central.at(r));
    }
    json jr;
    const fs::path gt_path = ds / ("robot_" + std::to_string(r)) / "groundtruth.tum";
    geometry::Trajectory gt;
    if (fs::exists(gt_path)) gt = geometry::read_tum(gt_path.string());
    jr["keyframes_source"] = central.count(r) ? "central's final graph" : "peer optimiser";
    for (const char* name : {"odometry", "keyframes", "keyframes_central"}) {  // every trajectory in KITTI format too
      const fs::path tum = rd / (std::string(name) + ".tum");
      if (fs::exists(tum)) geometry::write_kitti((rd / (std::string(name) + ".kitti")).string(), geometry::read_tum(tum.string()));
    }
    for (const char* kind : {"odometry", "keyframes"}) {
      const std::string file = std::string(kind) == "keyframes" && central.count(r) ? "keyframes_central" : kind;
      const fs::path tum = rd / (file + ".tum");
      if (!fs::exists(tum)) {
        jr[kind] = {{"error", "no trajectory written"}};
        continue;
      }
      const geometry::Trajectory est = geometry::read_tum(tum.string());
      if (gt.size() < 2 || est.size() < 2) {
        jr[kind] = {{"error", "too few poses"}, {"poses", est.size()}};
        continue;
      }
      try {
        eval::Evaluation e = eval::evaluate("robot " + std::to_string(r) + " " + kind, est, gt, eo);
        json je = eval::to_json(e, eo);
        je["ate_pct_of_length"] = e.gt_length_m > 0 ? 100.0 * e.ate.translation.rmse / e.gt_length_m : 0.0;
        jr[kind] = je;
        if (std::string(kind) == "keyframes") {
          e.name = "robot " + std::to_string(r);
          kf_evals.push_back(std::move(e));
        }
      } catch (const std::exception& ex) {
        jr[kind] = {{"error", ex.what()}};
      }
    }
    const std::vector<Transition> tr = read_modes(rd / "modes.csv");
    modes[r] = tr;
    json jt = json::array();
    size_t to_dist = 0, to_cent = 0, by_liveliness = 0;
    for (const Transition& t : tr) {
      jt.push_back({{"sim_s", static_cast<double>(t.sim_ns) * 1e-9}, {"from", t.from}, {"to", t.to}, {"reason", t.reason}});
      all_modes << r << ',' << t.wall_ns << ',' << t.sim_ns << ',' << t.from << ',' << t.to << ',' << t.reason << '\n';
      if (t.to == "DISTRIBUTED") ++to_dist;
      if (t.to == "CENTRALIZED") ++to_cent;
      if (t.reason.find("liveliness") != std::string::npos) ++by_liveliness;
      if (!gt.empty() && t.sim_ns > 0) {  // (not the start-up transition before the first sweep)
        eval::SvgMarker m;
        m.position = gt_position(gt, t.sim_ns);
        m.triangle = t.to == "DISTRIBUTED";
        m.color = eval::plot_color(k);
        m.label = (t.to == "DISTRIBUTED" ? "D " : "C ") + fixed(static_cast<double>(t.sim_ns) * 1e-9, 0) + " s";
        markers.push_back(m);
      }
    }
    jr["transitions"] = jt;
    jr["switches_to_distributed"] = to_dist;
    jr["switches_to_centralized"] = to_cent;
    jr["switches_on_liveliness_lost"] = by_liveliness;
    for (const char* svc : {"frontend", "descriptor", "loop_closure", "peer_optimiser"}) {
      const fs::path sp = rd / (std::string(svc) + ".stats.json");
      if (fs::exists(sp)) {
        try {
          std::ifstream in(sp);
          jr["stats"][svc] = json::parse(in);
        } catch (const std::exception&) {
          jr["stats"][svc] = {{"error", "unreadable"}};
        }
      }
    }
    // Traffic per mode and link.
    auto tit = info.traffic.find(r);
    if (info.traffic_measured && tit != info.traffic.end()) {
      json jm;
      for (const auto& [mode, peers] : tit->second.bytes) {
        const uint64_t kfs = tit->second.keyframes.count(mode) ? tit->second.keyframes.at(mode) : 0;
        for (const auto& [peer, b] : peers) {
          json l{{"sent_bytes", b.sent},
                 {"received_bytes", b.received},
                 {"discovery_sent_bytes", b.meta_sent},
                 {"discovery_received_bytes", b.meta_received},
                 {"keyframes_in_mode", kfs}};
          if (kfs > 0) {
            l["bytes_per_keyframe"] = static_cast<double>(b.sent + b.received) / static_cast<double>(kfs);
            l["sent_bytes_per_keyframe"] = static_cast<double>(b.sent) / static_cast<double>(kfs);
          }
          const uint64_t both = keyframes_both_ends(tit->second, mode, peer);
          l["keyframes_both_ends"] = both;
          if (both > 0) {
            l["bytes_per_keyframe_both_ends"] = static_cast<double>(b.sent + b.received) / static_cast<double>(both);
          }
          jm[mode][node_name(peer)] = l;
        }
      }
      jr["traffic"] = jm;
    }
    j["robots"][std::to_string(r)] = jr;
    ++k;
  }
  j["traffic_per_topic"] = topic_traffic(run, info.robots);
  // Link timeline.
  {
    std::ofstream lf(run / "links.csv");
    lf << "wall_s,sim_s,a,b,state\n";
    for (const LinkEvent& e : info.links) {
      lf << fixed(e.wall_s, 3) << ',' << fixed(e.sim_s, 3) << ',' << e.a << ',' << e.b << ',' << (e.up ? "up" : "down") << '\n';
    }
  }
  // Totals per mode and link, and the distributed traffic per keyframe on the worst link (robot to
  // robot or robot to central: a DISTRIBUTED robot sends the central no keyframes, only the little a
  // link that comes back carries before the robot rejoins).
  if (info.traffic_measured) {
    json per_link;
    double worst_dist_per_kf = 0, worst_dist_sent_per_kf = 0, worst_dist_both = 0;
    for (const auto& [r, t] : info.traffic) {
      for (const auto& [mode, peers] : t.bytes) {
        for (const auto& [peer, b] : peers) {
          const std::string link = node_name(r) + "-" + node_name(peer);
          per_link[link][mode]["sent_bytes"] = b.sent;
          per_link[link][mode]["received_bytes"] = b.received;
          per_link[link][mode]["discovery_bytes"] = b.meta_sent + b.meta_received;
          const uint64_t kfs = t.keyframes.count(mode) ? t.keyframes.at(mode) : 0;
          if (mode == "DISTRIBUTED" && kfs > 0) {
            worst_dist_per_kf = std::max(worst_dist_per_kf, static_cast<double>(b.sent + b.received) / static_cast<double>(kfs));
            worst_dist_sent_per_kf = std::max(worst_dist_sent_per_kf, static_cast<double>(b.sent) / static_cast<double>(kfs));
          }
          const uint64_t both = keyframes_both_ends(t, mode, peer);
          if (mode == "DISTRIBUTED" && both > 0) {
            worst_dist_both = std::max(worst_dist_both, static_cast<double>(b.sent + b.received) / static_cast<double>(both));
          }
        }
      }
    }
    // Whole run, per robot-to-robot link (every mode): what is sent in one mode can be charged to
    // the next (a backlog of descriptors made while out of range crosses when the link returns), so
    // the run's user data on each link is also divided by the keyframes both ends made.
    json whole = json::object();
    double worst_whole = 0;
    for (const auto& [r, t] : info.traffic) {
      uint64_t kf_r = 0;
      for (const auto& [mode, n] : t.keyframes) kf_r += n;
      std::map<uint32_t, uint64_t> bytes;
      for (const auto& [mode, peers] : t.bytes) {
        for (const auto& [peer, b] : peers) bytes[peer] += b.sent + b.received;
      }
      for (const auto& [peer, total] : bytes) {
        if (peer == kCentralNode || peer <= r) continue;  // each robot pair once, as counted at the lower id
        const auto pt = info.traffic.find(peer);
        uint64_t kf_p = 0;
        if (pt != info.traffic.end()) {
          for (const auto& [mode, n] : pt->second.keyframes) kf_p += n;
        }
        json l{{"user_bytes", total}, {"keyframes_both_ends", kf_r + kf_p}};
        if (kf_r + kf_p > 0) {
          const double per = static_cast<double>(total) / static_cast<double>(kf_r + kf_p);
          l["bytes_per_keyframe"] = per;
          worst_whole = std::max(worst_whole, per);
        }
        whole[node_name(r) + "-" + node_name(peer)] = l;
      }
    }
    j["traffic"] = {{"per_link", per_link},
                    {"robot_links_whole_run", whole},
                    {"max_robot_link_bytes_per_keyframe_whole_run", worst_whole},
                    {"max_distributed_bytes_per_keyframe_per_link", worst_dist_per_kf},
                    {"max_distributed_sent_bytes_per_own_keyframe_per_link", worst_dist_sent_per_kf},
                    {"max_distributed_bytes_per_keyframe_both_ends_per_link", worst_dist_both}};
  }
  // Plots.
  if (!kf_evals.empty()) {
    const fs::path svg = run / "trajectories.svg";
    std::ofstream(svg) << eval::render_svg(kf_evals, "xy", info.name + ": optimised keyframes against ground truth", markers,
                                           "triangle: switch to DISTRIBUTED, circle: back to CENTRALIZED (sim time)");
    write_png(svg);
  }
  {
    const fs::path svg = run / "modes.svg";
    std::ofstream(svg) << render_timeline(info, modes);
    write_png(svg);
  }
  // report.md
  std::ostringstream md;
  md << "# Run " << info.name << "\n\n"
     << "- variant: " << info.variant << ", network: " << info.network << ", robots: " << info.robots.size() << "\n"
     << "- dataset: `" << info.dataset << "`\n- wall time: " << fixed(info.wall_s, 1) << " s for " << fixed(info.sim_end_s, 1)
     << " s of sim time" << (info.interrupted ? " (interrupted)" : "") << "\n";
  for (const auto& n : info.notes) md << "- note: " << n << "\n";
  if (info.rendezvous_s) {
    md << "- final rendezvous: ";
    if (info.not_rejoined.empty()) {
      md << "every robot CENTRALIZED, the central holding all its keyframes, " << fixed(*info.rendezvous_s, 1)
         << " s after the last sweep";
    } else {
      md << "**robot";
      for (uint32_t r : info.not_rejoined) md << ' ' << r;
      md << " not CENTRALIZED, or some of its keyframes not with the central, after " << fixed(*info.rendezvous_s, 1)
         << " s**";
    }
    if (info.caught_up_s) {
      md << "; every loop closure caught up (peers' descriptors searched, their clouds received) "
         << fixed(*info.caught_up_s, 1) << " s after the last sweep\n";
    } else {
      md << "; **loop closure of robot";
      for (uint32_t r : info.loop_closure_busy) md << ' ' << r;
      md << " not caught up at the end**\n";
    }
  }
  md << "\n## Accuracy (SE(3)-aligned per robot)\n\n"
     << "| robot | trajectory | length m | ATE rmse m | ATE % of length | RPE 1-step m | RPE 100 m (m) |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (uint32_t r : info.robots) {
    const json& jr = j["robots"][std::to_string(r)];
    for (const char* kind : {"odometry", "keyframes"}) {
      const json& e = jr[kind];
      if (!e.contains("ate_m")) {
        md << "| " << r << " | " << kind << " | - | " << e.value("error", std::string("?")) << " | | | |\n";
        continue;
      }
      md << "| " << r << " | " << kind << " | " << fixed(e["gt_length_m"].get<double>(), 1) << " | "
         << fixed(e["ate_m"]["rmse"].get<double>(), 3) << " | " << fixed(e["ate_pct_of_length"].get<double>(), 3) << " | "
         << fixed(e["rpe_frames"]["trans_m"]["rmse"].get<double>(), 3) << " | "
         << fixed(e["rpe_distance"]["trans_m"]["rmse"].get<double>(), 3) << " |\n";
    }
  }
  md << "\n## Mode switches\n\n| robot | to DISTRIBUTED | back to CENTRALIZED | on liveliness lost | transitions (sim s) |\n"
     << "|---|---|---|---|---|\n";
  for (uint32_t r : info.robots) {
    const json& jr = j["robots"][std::to_string(r)];
    std::string list;
    for (const auto& t : jr["transitions"]) {
      list += (list.empty() ? "" : ", ") + t["to"].get<std::string>().substr(0, 1) + "@" + fixed(t["sim_s"].get<double>(), 1) +
              " (" + t["reason"].get<std::string>() + ")";
    }
    md << "| " << r << " | " << jr["switches_to_distributed"] << " | " << jr["switches_to_centralized"] << " | "
       << jr["switches_on_liveliness_lost"] << " | " << list << " |\n";
  }
  {
    // Each robot's loop closure: loops found and how long they took from the later keyframe's
    // descriptor reaching the service to the loop going out (wall time).
    std::ostringstream rows;
    for (uint32_t r : info.robots) {
      const json& jr = j["robots"][std::to_string(r)];
      if (!jr.contains("stats") || !jr["stats"].contains("loop_closure")) continue;
      const json& ls = jr["stats"]["loop_closure"];
      if (!ls.contains("loop_latency_s")) continue;
      const json& lat = ls["loop_latency_s"];
      rows << "| " << r << " | " << ls.value("intra_accepted", 0) << " | " << ls.value("inter_accepted", 0) << " | "
           << (lat.value("count", 0) == 0 ? std::string("- (none published)")
                                          : fixed(lat.value("median", 0.0), 1) + " / " + fixed(lat.value("p90", 0.0), 1) +
                                                " / " + fixed(lat.value("max", 0.0), 1))
           << " |\n";
    }
    if (!rows.str().empty()) {
      md << "\n## Loop closure\n\nLatency: from the later keyframe's descriptor reaching the robot's loop closure to "
            "the loop going out (wall seconds).\n\n| robot | own loops | loops with peers | latency median / p90 / max [s] |\n"
         << "|---|---|---|---|\n"
         << rows.str();
    }
  }
  if (info.traffic_measured) {
    md << "\n## Traffic on the emulated radio (SLAM domain, IP bytes, counted at each robot)\n\n"
       << "User data (samples with their heartbeats and acknowledgements) and discovery (SPDP/SEDP, which bursts\n"
       << "whenever a link comes back) are counted apart. Each mode gets what was counted while the robot was in it;\n"
       << "a sample (about a second) in which the robot switched goes to CENTRALIZED, whose traffic it carries: the\n"
       << "keyframes sent until the link was cut, or the backlog re-sent right after a rejoin. RENDEZVOUS: after the\n"
       << "last sweep, when the final rendezvous brings every robot back in range (the catch-up: backlogs, and the\n"
       << "loops that could not be closed out of range with the clouds they need), whatever the robot's mode.\n\n"
       << "Per keyframe: the robot's own keyframes made in the mode. A robot's keyframe costs what it sends on a\n"
       << "link (its descriptor, the clouds it serves, acknowledgements); what it receives is the other end's cost.\n"
       << "Both ends: the link's data both ways per keyframe made at either end while the robot was in the mode\n"
       << "(to the central: its own keyframes only).\n\n"
       << "| link | mode | data sent | data received | discovery | keyframes in mode | sent per keyframe | sent + received per keyframe | keyframes, both ends | sent + received per keyframe, both ends |\n"
       << "|---|---|---|---|---|---|---|---|---|---|\n";
    for (const auto& [r, t] : info.traffic) {
      for (const auto& [mode, peers] : t.bytes) {
        const uint64_t kfs = t.keyframes.count(mode) ? t.keyframes.at(mode) : 0;
        for (const auto& [peer, b] : peers) {
          const uint64_t both = keyframes_both_ends(t, mode, peer);
          md << "| " << node_name(r) << " - " << node_name(peer) << " | " << mode << " | " << b.sent << " | " << b.received
             << " | " << b.meta_sent + b.meta_received << " | " << kfs << " | "
             << (kfs > 0 ? fixed(static_cast<double>(b.sent) / static_cast<double>(kfs), 0) : std::string("-")) << " | "
             << (kfs > 0 ? fixed(static_cast<double>(b.sent + b.received) / static_cast<double>(kfs), 0) : std::string("-"))
             << " | " << both << " | "
             << (both > 0 ? fixed(static_cast<double>(b.sent + b.received) / static_cast<double>(both), 0) : std::string("-"))
             << " |\n";
        }
      }
    }
    md << "\nLargest distributed-mode user data per own keyframe on a link (to a robot or to the central): "
       << fixed(j["traffic"]["max_distributed_sent_bytes_per_own_keyframe_per_link"].get<double>(), 0) << " B sent ("
       << fixed(j["traffic"]["max_distributed_bytes_per_keyframe_per_link"].get<double>(), 0)
       << " B sent and received); per keyframe made at either end: "
       << fixed(j["traffic"]["max_distributed_bytes_per_keyframe_both_ends_per_link"].get<double>(), 0)
       << " B sent and received\n"
       << "\nWhole run, user data on each robot-to-robot link (both directions, every mode) per keyframe made by\n"
       << "either end (a backlog made while out of range crosses when the link returns, in the next mode):\n\n"
       << "| link | user data | keyframes (both ends) | bytes per keyframe |\n|---|---|---|---|\n";
    for (const auto& [link, l] : j["traffic"]["robot_links_whole_run"].items()) {
      md << "| " << link << " | " << l["user_bytes"] << " | " << l["keyframes_both_ends"] << " | "
         << (l.contains("bytes_per_keyframe") ? fixed(l["bytes_per_keyframe"].get<double>(), 0) : std::string("-")) << " |\n";
    }
  }
  {
    const std::string slam = std::to_string(info.slam_domain), sim = std::to_string(info.sim_domain);
    md << "\n## Traffic per topic (serialised payload, written and taken by each service)\n\n"
       << "Counted by the DDS layer of every service: a sample written once counts once however many readers\n"
       << "it reaches (on the radio it crosses every link to a matched reader, see above). Domain " << slam
       << " is the SLAM domain, the only one on the emulated radio; " << sim << " is the simulator's (sensors, lock-step);\n"
       << "the others are each robot's own (front-end to its peer optimiser, never on the radio).\n\n"
       << "| node | service | domain | topic | samples written | bytes written | samples taken | bytes taken |\n"
       << "|---|---|---|---|---|---|---|---|\n";
    for (const auto& [node, services] : j["traffic_per_topic"].items()) {
      for (const auto& [service, domains] : services.items()) {
        for (const auto& [domain, topics] : domains.items()) {
          const std::string label = domain == slam ? domain + " (SLAM)" : domain == sim ? domain + " (sim)" : domain + " (robot)";
          for (const auto& [topic, c] : topics.items()) {
            md << "| " << node << " | " << service << " | " << label << " | `" << topic << "` | " << c["samples_written"] << " | "
               << c["bytes_written"] << " | " << c["samples_taken"] << " | " << c["bytes_taken"] << " |\n";
          }
        }
      }
    }
  }
  md << "\n## Files\n\n- `robot_K/odometry.{tum,kitti}`: the front-end's real-time odometry (fused pose)\n"
     << "- `robot_K/keyframes.{tum,kitti}`: the robot's keyframes in the world frame as its peer optimiser last had them;\n"
     << "  `robot_K/keyframes_central.{tum,kitti}`: the same keyframes in the central's final graph (evaluated when present)\n"
     << "- `global_graph.g2o`: the central's graph; `map/map.pcd`, `map/map.bt`: the global map\n"
     << "- `modes.csv`, `links.csv`: mode timeline and emulated link changes; `traffic.csv` (netns): the bytes counted\n"
     << "  per robot and link in every half-second sample, with the robot's mode; `logs/`: one log per process\n"
     << "- `trajectories.svg|png`, `modes.svg|png`: plots\n";
  std::ofstream(run / "report.md") << md.str();
  std::ofstream(run / "report.json") << j.dump(2) << '\n';
  return j;
}

std::optional<PositionDifference> position_difference(const std::string& tum_a, const std::string& tum_b) {
  if (!fs::exists(tum_a) || !fs::exists(tum_b)) return std::nullopt;
  const geometry::Trajectory a = geometry::read_tum(tum_a), b = geometry::read_tum(tum_b);
  const auto pairs = geometry::associate(a, b, 5'000'000);
  if (pairs.empty()) return std::nullopt;
  PositionDifference d;
  double sum = 0;
  for (const auto& [i, j] : pairs) {
    const double e = (a[i].pose.translation() - b[j].pose.translation()).norm();
    sum += e * e;
    d.max_m = std::max(d.max_m, e);
  }
  d.matched = pairs.size();
  d.rms_m = std::sqrt(sum / static_cast<double>(pairs.size()));
  return d;
}

// Several runs of one variant: per robot the median of each figure over the runs that have it, the
// smallest and largest real-time ATE, and every run's ATE.
json merge_runs(const std::vector<json>& rows) {
  if (rows.size() == 1) return rows.front();
  json out;
  out["runs"] = rows.size();
  std::vector<double> walls;
  for (const json& r : rows) walls.push_back(r.value("wall_s", 0.0));
  out["wall_s"] = geometry::compute_stats(walls).median;
  std::set<std::string> robots;
  for (const json& r : rows) {
    if (r.contains("robots")) {
      for (const auto& [robot, _] : r["robots"].items()) robots.insert(robot);
    }
  }
  for (const std::string& robot : robots) {
    json m;
    for (const char* key : {"ate_m", "rpe_m", "length_m", "keyframes_ate_m", "corrections", "switches_to_distributed"}) {
      std::vector<double> v;
      for (const json& r : rows) {
        if (r.contains("robots") && r["robots"].contains(robot) && r["robots"][robot].contains(key)) {
          v.push_back(r["robots"][robot][key].get<double>());
        }
      }
      if (v.empty()) continue;
      const geometry::ErrorStats st = geometry::compute_stats(v);
      m[key] = st.median;
      if (std::string(key) == "ate_m") {
        m["ate_m_runs"] = v;
        m["ate_m_min"] = st.min;
        m["ate_m_max"] = st.max;
      }
    }
    if (m.contains("corrections")) m["corrections"] = static_cast<uint64_t>(m["corrections"].get<double>());
    out["robots"][robot] = m;
  }
  return out;
}

}  // namespace cdc::launch
