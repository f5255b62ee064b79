#include "report_render.hpp"

#include <algorithm>
#include <sstream>

namespace cdc::launch {
using nlohmann::json;

namespace {

std::string fixed_or_dash(const std::optional<double>& v, int decimals) { return v ? fixed(*v, decimals) : "-"; }

void write_rendezvous(std::ostream& md, const RunInfo& info) {
  md << "- final rendezvous: ";
  if (info.not_rejoined.empty()) {
    md << "every robot CENTRALIZED, the central holding all its keyframes, " << fixed(*info.rendezvous_s, 1)
       << " s after the last sweep";
  } else {
    md << "**robot" << id_list(info.not_rejoined)
       << " not CENTRALIZED, or some of its keyframes not with the central, after " << fixed(*info.rendezvous_s, 1)
       << " s**";
  }
  if (info.caught_up_s) {
    md << "; every loop closure caught up (peers' descriptors searched, their clouds received) "
       << fixed(*info.caught_up_s, 1) << " s after the last sweep\n";
  } else {
    md << "; **loop closure of robot" << id_list(info.loop_closure_busy) << " not caught up at the end**\n";
  }
}

void write_header(std::ostream& md, const RunInfo& info) {
  md << "# Run " << info.name << "\n\n"
     << "- variant: " << info.variant << ", network: " << info.network << ", robots: " << info.robots.size() << "\n"
     << "- dataset: `" << info.dataset << "`\n- wall time: " << fixed(info.wall_s, 1) << " s for "
     << fixed(info.sim_end_s, 1) << " s of sim time" << (info.interrupted ? " (interrupted)" : "") << "\n";
  for (const auto& n : info.notes) md << "- note: " << n << "\n";
  if (info.rendezvous_s) write_rendezvous(md, info);
}

void write_accuracy(std::ostream& md, const std::vector<RobotResult>& robots) {
  md << "\n## Accuracy (SE(3)-aligned per robot)\n\n"
     << "| robot | trajectory | length m | ATE rmse m | ATE % of length | RPE 1-step m | RPE 100 m (m) |\n"
     << "|---|---|---|---|---|---|---|\n";
  for (const RobotResult& r : robots) {
    for (const auto& [kind, t] :
         {std::pair<const char*, const TrajectoryResult*>{"odometry", &r.odometry}, {"keyframes", &r.keyframes}}) {
      md << "| " << r.robot << " | " << kind << " | ";
      if (!t->evaluation) {
        md << "- | " << t->error << " | | | |\n";
        continue;
      }
      const eval::Evaluation& e = *t->evaluation;
      md << fixed(e.gt_length_m, 1) << " | " << fixed(e.ate.translation.rmse, 3) << " | "
         << fixed(t->ate_pct_of_length(), 3) << " | " << fixed(e.rpe_frames.translation.rmse, 3) << " | "
         << fixed(e.rpe_distance.translation.rmse, 3) << " |\n";
    }
  }
}

void write_mode_switches(std::ostream& md, const std::vector<RobotResult>& robots) {
  md << "\n## Mode switches\n\n| robot | to DISTRIBUTED | back to CENTRALIZED | on liveliness lost | transitions (sim "
        "s) |\n"
     << "|---|---|---|---|---|\n";
  for (const RobotResult& r : robots) {
    std::string list;
    for (const Transition& t : r.transitions) {
      list += (list.empty() ? "" : ", ") + t.to.substr(0, 1) + "@" + fixed(static_cast<double>(t.sim_ns) * 1e-9, 1) +
              " (" + t.reason + ")";
    }
    md << "| " << r.robot << " | " << r.switches.to_distributed << " | " << r.switches.to_centralized << " | "
       << r.switches.on_liveliness_lost << " | " << list << " |\n";
  }
}

// Each robot's loop closure: loops found and how long they took from the later keyframe's descriptor
// reaching the service to the loop going out (wall time). Only robots whose stats say so get a row.
void write_loop_closure(std::ostream& md, const std::vector<RobotResult>& robots) {
  std::ostringstream rows;
  for (const RobotResult& r : robots) {
    if (!r.stats.contains("loop_closure")) continue;
    const json& ls = r.stats["loop_closure"];
    if (!ls.contains("loop_latency_s")) continue;
    const json& lat = ls["loop_latency_s"];
    rows << "| " << r.robot << " | " << ls.value("intra_accepted", 0) << " | " << ls.value("inter_accepted", 0) << " | "
         << (lat.value("count", 0) == 0 ? std::string("- (none published)")
                                        : fixed(lat.value("median", 0.0), 1) + " / " + fixed(lat.value("p90", 0.0), 1) +
                                              " / " + fixed(lat.value("max", 0.0), 1))
         << " |\n";
  }
  if (rows.str().empty()) return;
  md << "\n## Loop closure\n\nLatency: from the later keyframe's descriptor reaching the robot's loop closure to "
        "the loop going out (wall seconds).\n\n| robot | own loops | loops with peers | latency median / p90 / max [s] "
        "|\n"
     << "|---|---|---|---|\n"
     << rows.str();
}

void write_radio_traffic_per_mode(std::ostream& md, const TrafficSummary& traffic) {
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
     << "| link | mode | data sent | data received | discovery | keyframes in mode | sent per keyframe | sent + "
        "received per keyframe | keyframes, both ends | sent + received per keyframe, both ends |\n"
     << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const LinkModeTraffic& l : traffic.links) {
    md << "| " << node_name(l.robot) << " - " << node_name(l.peer) << " | " << l.mode << " | " << l.bytes.sent << " | "
       << l.bytes.received << " | " << l.bytes.meta_sent + l.bytes.meta_received << " | " << l.keyframes_in_mode
       << " | " << fixed_or_dash(l.sent_per_keyframe(), 0) << " | " << fixed_or_dash(l.bytes_per_keyframe(), 0) << " | "
       << l.keyframes_both_ends << " | " << fixed_or_dash(l.bytes_per_keyframe_both_ends(), 0) << " |\n";
  }
}

void write_radio_traffic_totals(std::ostream& md, const TrafficSummary& traffic) {
  md << "\nLargest distributed-mode user data per own keyframe on a link (to a robot or to the central): "
     << fixed(traffic.max_distributed_sent_bytes_per_own_keyframe_per_link, 0) << " B sent ("
     << fixed(traffic.max_distributed_bytes_per_keyframe_per_link, 0)
     << " B sent and received); per keyframe made at either end: "
     << fixed(traffic.max_distributed_bytes_per_keyframe_both_ends_per_link, 0) << " B sent and received\n"
     << "\nWhole run, user data on each robot-to-robot link (both directions, every mode) per keyframe made by\n"
     << "either end (a backlog made while out of range crosses when the link returns, in the next mode):\n\n"
     << "| link | user data | keyframes (both ends) | bytes per keyframe |\n|---|---|---|---|\n";
  for (const auto& [link, p] : traffic.robot_links_whole_run) {
    md << "| " << link << " | " << p.user_bytes << " | " << p.keyframes_both_ends << " | "
       << fixed_or_dash(p.bytes_per_keyframe(), 0) << " |\n";
  }
}

void write_topic_traffic(std::ostream& md, const RunInfo& info, const json& topics) {
  const std::string slam = std::to_string(info.slam_domain), sim = std::to_string(info.sim_domain);
  md << "\n## Traffic per topic (serialised payload, written and taken by each service)\n\n"
     << "Counted by the DDS layer of every service: a sample written once counts once however many readers\n"
     << "it reaches (on the radio it crosses every link to a matched reader, see above). Domain " << slam
     << " is the SLAM domain, the only one on the emulated radio; " << sim
     << " is the simulator's (sensors, lock-step);\n"
     << "the others are each robot's own (front-end to its peer optimiser, never on the radio).\n\n"
     << "| node | service | domain | topic | samples written | bytes written | samples taken | bytes taken |\n"
     << "|---|---|---|---|---|---|---|---|\n";
  for (const auto& [node, services] : topics.items()) {
    for (const auto& [service, domains] : services.items()) {
      for (const auto& [domain, per_topic] : domains.items()) {
        const std::string label = domain == slam  ? domain + " (SLAM)"
                                  : domain == sim ? domain + " (sim)"
                                                  : domain + " (robot)";
        for (const auto& [topic, c] : per_topic.items()) {
          md << "| " << node << " | " << service << " | " << label << " | `" << topic << "` | " << c["samples_written"]
             << " | " << c["bytes_written"] << " | " << c["samples_taken"] << " | " << c["bytes_taken"] << " |\n";
        }
      }
    }
  }
}

void write_files(std::ostream& md) {
  md << "\n## Files\n\n- `robot_K/odometry.{tum,kitti}`: the front-end's real-time odometry (fused pose)\n"
     << "- `robot_K/keyframes.{tum,kitti}`: the robot's keyframes in the world frame as its peer optimiser last had "
        "them;\n"
     << "  `robot_K/keyframes_central.{tum,kitti}`: the same keyframes in the central's final graph (evaluated when "
        "present)\n"
     << "- `global_graph.g2o`: the central's graph; `map/map.pcd`, `map/map.bt`: the global map\n"
     << "- `modes.csv`, `links.csv`: mode timeline and emulated link changes; `traffic.csv` (netns): the bytes "
        "counted\n"
     << "  per robot and link in every half-second sample, with the robot's mode; `logs/`: one log per process\n"
     << "- `trajectories.svg|png`, `modes.svg|png`: plots\n";
}

// The timeline's geometry: a row per robot, sim time from 0 to the run's end along x.
class Timeline {
 public:
  explicit Timeline(const RunInfo& info)
      : info_(info),
        height_(kTop + kRow * static_cast<double>(info.robots.size()) + 60),
        t_end_(std::max(info.sim_end_s, 1.0)) {}

  std::string render(const std::vector<RobotResult>& robots) {
    s_ << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << kWidth << "\" height=\"" << height_
       << "\" font-family=\"sans-serif\" font-size=\"12\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n"
       << "<text x=\"" << kLeft << "\" y=\"24\" font-size=\"15\">" << info_.name
       << ": back-end mode over sim time</text>\n";
    double y = kTop;
    for (const RobotResult& r : robots) {
      s_ << "<text x=\"10\" y=\"" << y + 16 << "\">robot " << r.robot << "</text>\n";
      mode_bars(r, y);
      cut_bars(r.robot, y);
      y += kRow;
    }
    axis_and_legend(y);
    return s_.str();
  }

 private:
  static constexpr double kWidth = 900, kLeft = 90, kRight = 20, kRow = 46, kTop = 50;

  double px(double t) const { return kLeft + (kWidth - kLeft - kRight) * std::clamp(t / t_end_, 0.0, 1.0); }

  void bar(double a, double b, double y, double height, const char* color) {
    s_ << "<rect x=\"" << fixed(px(a), 1) << "\" y=\"" << y << "\" width=\"" << fixed(std::max(px(b) - px(a), 0.5), 1)
       << "\" height=\"" << height << "\" fill=\"" << color << "\"/>\n";
  }

  // The robot's mode from the start (the run's first mode) through each transition to the end.
  void mode_bars(const RobotResult& r, double y) {
    auto colour = [](const std::string& m) { return m == "CENTRALIZED" ? "#1f77b4" : "#ff7f0e"; };
    std::string mode = info_.central ? "CENTRALIZED" : "DISTRIBUTED";
    double t0 = 0;
    for (const Transition& t : r.transitions) {
      const double ts = static_cast<double>(t.sim_ns) * 1e-9;
      bar(t0, ts, y, 22, colour(mode));
      mode = t.to;
      t0 = ts;
    }
    bar(t0, t_end_, y, 22, colour(mode));
  }

  // The periods the robot's link to the central was cut (grey), under its mode bar.
  void cut_bars(uint32_t robot, double y) {
    double cut_start = -1;  // < 0: the link is up
    for (const LinkEvent& e : info_.links) {
      if (!((e.a == robot && e.b == kCentralNode) || (e.b == robot && e.a == kCentralNode))) continue;
      if (!e.up && cut_start < 0) cut_start = e.sim_s;
      if (e.up && cut_start >= 0) {
        bar(cut_start, e.sim_s, y + 25, 6, "#777777");
        cut_start = -1;
      }
    }
    if (cut_start >= 0) bar(cut_start, t_end_, y + 25, 6, "#777777");
  }

  void axis_and_legend(double y) {
    s_ << "<line x1=\"" << kLeft << "\" y1=\"" << y << "\" x2=\"" << kWidth - kRight << "\" y2=\"" << y
       << "\" stroke=\"black\"/>\n";
    const double step = t_end_ > 200 ? 50 : t_end_ > 50 ? 10 : 5;
    for (double t = 0; t <= t_end_ + 1e-9; t += step) {
      s_ << "<line x1=\"" << fixed(px(t), 1) << "\" y1=\"" << y << "\" x2=\"" << fixed(px(t), 1) << "\" y2=\"" << y + 5
         << "\" stroke=\"black\"/><text x=\"" << fixed(px(t) - 8, 1) << "\" y=\"" << y + 18 << "\">" << fixed(t, 0)
         << "</text>\n";
    }
    s_ << "<text x=\"" << kWidth - kRight - 60 << "\" y=\"" << y + 34 << "\">sim time [s]</text>\n"
       << "<rect x=\"" << kLeft << "\" y=\"" << y + 26 << "\" width=\"12\" height=\"10\" fill=\"#1f77b4\"/><text x=\""
       << kLeft + 16 << "\" y=\"" << y + 35 << "\">CENTRALIZED</text>"
       << "<rect x=\"" << kLeft + 120 << "\" y=\"" << y + 26
       << "\" width=\"12\" height=\"10\" fill=\"#ff7f0e\"/><text x=\"" << kLeft + 136 << "\" y=\"" << y + 35
       << "\">DISTRIBUTED</text>"
       << "<rect x=\"" << kLeft + 240 << "\" y=\"" << y + 29
       << "\" width=\"12\" height=\"5\" fill=\"#777777\"/><text x=\"" << kLeft + 256 << "\" y=\"" << y + 35
       << "\">link to the central cut (emulated radio)</text>\n</svg>\n";
  }

  const RunInfo& info_;
  const double height_, t_end_;
  std::ostringstream s_;
};

}  // namespace

std::string render_markdown(const RunInfo& info, const std::vector<RobotResult>& robots,
                            const std::optional<TrafficSummary>& traffic, const json& topics) {
  std::ostringstream md;
  write_header(md, info);
  write_accuracy(md, robots);
  write_mode_switches(md, robots);
  write_loop_closure(md, robots);
  if (traffic) {
    write_radio_traffic_per_mode(md, *traffic);
    write_radio_traffic_totals(md, *traffic);
  }
  write_topic_traffic(md, info, topics);
  write_files(md);
  return md.str();
}

std::string render_timeline(const RunInfo& info, const std::vector<RobotResult>& robots) {
  return Timeline(info).render(robots);
}

}  // namespace cdc::launch
