#include "report.hpp"

#include "process.hpp"
#include "report_render.hpp"
#include "report_results.hpp"

#include "cdc/eval/evaluation.hpp"
#include "cdc/geometry/metrics.hpp"
#include "cdc/geometry/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

namespace cdc::launch {
namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// The run as a whole: what ran, on what, for how long, and how the final rendezvous went.
json run_json(const RunInfo& info) {
  json j{{"name", info.name},
         {"variant", info.variant},
         {"network", info.network},
         {"dataset", info.dataset},
         {"swarm_file", info.swarm_file},
         {"wall_s", info.wall_s},
         {"sim_s", info.sim_end_s},
         {"interrupted", info.interrupted},
         {"notes", info.notes},
         {"domains", {{"slam", info.slam_domain}, {"sim", info.sim_domain}}}};
  if (info.rendezvous_s) {
    j["rendezvous"] = {{"waited_s", *info.rendezvous_s},
                       {"not_rejoined", info.not_rejoined},
                       {"loop_closure_busy", info.loop_closure_busy}};
    if (info.caught_up_s) j["rendezvous"]["loop_closure_caught_up_s"] = *info.caught_up_s;
  }
  if (!info.faults.empty()) {
    j["radio_faults"] = {{"changes", info.faults.size()}, {"dropped_datagrams", info.fault_dropped_datagrams}};
  }
  return j;
}

json report_json(const RunInfo& info, const std::vector<RobotResult>& robots,
                 const std::optional<TrafficSummary>& traffic, const json& topics, const eval::EvalOptions& options) {
  json j = run_json(info);
  for (const RobotResult& r : robots) {
    json jr = r.to_json(options);
    if (traffic && info.traffic.count(r.robot)) jr["traffic"] = traffic->robot_json(r.robot);
    j["robots"][std::to_string(r.robot)] = jr;
  }
  j["traffic_per_topic"] = topics;
  if (traffic) j["traffic"] = traffic->to_json();
  return j;
}

// modes.csv: every robot's transitions, robot by robot.
void write_mode_log(const fs::path& path, const std::vector<RobotResult>& robots) {
  std::ofstream out(path);
  out << "robot,wall_ns,sim_ns,from,to,reason\n";
  for (const RobotResult& r : robots) {
    for (const Transition& t : r.transitions) {
      out << r.robot << ',' << t.wall_ns << ',' << t.sim_ns << ',' << t.from << ',' << t.to << ',' << t.reason << '\n';
    }
  }
}

// links.csv: every change of an emulated link.
void write_link_log(const fs::path& path, const std::vector<LinkEvent>& links) {
  std::ofstream out(path);
  out << "wall_s,sim_s,a,b,state\n";
  for (const LinkEvent& e : links) {
    out << fixed(e.wall_s, 3) << ',' << fixed(e.sim_s, 3) << ',' << e.a << ',' << e.b << ',' << (e.up ? "up" : "down")
        << '\n';
  }
}

// faults.csv: every change of a radio fault's drop probability on a directed pair (when any).
void write_fault_log(const fs::path& path, const std::vector<FaultEvent>& faults) {
  if (faults.empty()) return;
  std::ofstream out(path);
  out << "wall_s,sim_s,src,dst,drop\n";
  for (const FaultEvent& e : faults) {
    out << fixed(e.wall_s, 3) << ',' << fixed(e.sim_s, 3) << ',' << e.src << ',' << e.dst << ',' << fixed(e.drop, 4)
        << '\n';
  }
}

void write_svg_and_png(const fs::path& svg, const std::string& content) {
  std::ofstream(svg) << content;
  fs::path png = svg;
  png.replace_extension(".png");
  run_command({"rsvg-convert", "-o", png.string(), svg.string()});  // optional: librsvg2-bin
}

// trajectories.svg: every robot's evaluated keyframes against ground truth, with its mode switches;
// modes.svg: the mode timeline.
void write_plots(const RunInfo& info, const std::vector<RobotResult>& robots) {
  const fs::path run(info.run_dir);
  std::vector<eval::Evaluation> keyframes;
  std::vector<eval::SvgMarker> markers;
  for (const RobotResult& r : robots) {
    if (r.keyframes.evaluation) {
      keyframes.push_back(*r.keyframes.evaluation);
      keyframes.back().name = "robot " + std::to_string(r.robot);
    }
    markers.insert(markers.end(), r.markers.begin(), r.markers.end());
  }
  if (!keyframes.empty()) {
    write_svg_and_png(
        run / "trajectories.svg",
        eval::render_svg(keyframes, "xy", info.name + ": optimised keyframes against ground truth", markers,
                         "triangle: switch to DISTRIBUTED, circle: back to CENTRALIZED (sim time)"));
  }
  write_svg_and_png(run / "modes.svg", render_timeline(info, robots));
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

std::string id_list(const std::vector<uint32_t>& ids) {
  std::string s;
  for (uint32_t id : ids) s += ' ' + std::to_string(id);
  return s;
}

json write_report(const RunInfo& info) {
  const fs::path run(info.run_dir);
  const eval::EvalOptions options;
  // Final optimised keyframes: the central's final graph for the robots it holds, else the peer's.
  const auto central = central_trajectories(run / "global_graph.g2o", run, info.robots);
  std::vector<RobotResult> robots;
  for (size_t k = 0; k < info.robots.size(); ++k)
    robots.push_back(gather_robot(info, info.robots[k], k, central, options));
  std::optional<TrafficSummary> traffic;
  if (info.traffic_measured) traffic = summarise_traffic(info);
  const json topics = topic_traffic(run, info.robots);
  write_mode_log(run / "modes.csv", robots);
  write_link_log(run / "links.csv", info.links);
  write_fault_log(run / "faults.csv", info.faults);
  write_plots(info, robots);
  const json j = report_json(info, robots, traffic, topics, options);
  std::ofstream(run / "report.md") << render_markdown(info, robots, traffic, topics);
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
    for (const char* key :
         {"ate_m", "rpe_m", "length_m", "keyframes_ate_m", "corrections", "switches_to_distributed"}) {
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
