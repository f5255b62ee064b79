// cdc-launch: starts a whole simulated swarm (the simulator's player, every robot's services, the
// central node) from a swarm file, emulates the radio on real DDS traffic, shows progress, stops
// everything cleanly (also on Ctrl-C) and writes the run's results and report.
#include "cdc/config/cli_range.hpp"
#include "network.hpp"
#include "process.hpp"
#include "rendezvous.hpp"
#include "report.hpp"
#include "swarm.hpp"

#include "cdc/base/tool.hpp"
#include "cdc/config/reader.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>

namespace fs = std::filesystem;
using namespace cdc::launch;
using Clock = std::chrono::steady_clock;

namespace {

std::string timestamp() {
  const std::time_t t = std::time(nullptr);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y%m%d-%H%M%S", std::localtime(&t));
  return buf;
}

std::string read_file(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

struct RobotNow {
  std::string mode = "-";
  uint64_t keyframes = 0;
  bool central_alive = false;
  uint64_t acknowledged = 0;  // keyframes the central holds (all up to this id - 1)
};

// A peer optimiser's MODE_OUT.now (services/peer_optimiser/src/mode_files.hpp).
RobotNow read_now(const fs::path& p) {
  RobotNow r;
  std::istringstream in(read_file(p));
  uint64_t transitions = 0;
  int alive = 0;
  if (in >> r.mode >> r.keyframes >> transitions >> alive) r.central_alive = alive != 0;
  if (!(in >> r.acknowledged)) r.acknowledged = 0;
  return r;
}

// A loop-closure service's --backlog-out (services/loop_closure/src/loop_config.hpp): "<descriptors
// waiting> <requests pending> <requests parked> <loops published>". Caught up: nothing waiting.
bool loop_closure_caught_up(const fs::path& p) {
  std::istringstream in(read_file(p));
  uint64_t waiting = 0, pending = 0, parked = 0;
  return static_cast<bool>(in >> waiting >> pending >> parked) && waiting == 0 && pending == 0 && parked == 0;
}

// "(exit N): see LOG" of an ended process.
std::string exit_note(const Process& p) {
  return "(exit " + std::to_string(p.exit_status().value_or(-1)) + "): see " + p.spec().log_path;
}

Clock::duration to_duration(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

struct Options {
  std::string swarm, out, bin_dir = "build/release", root = ".", network, dataset;
  int max_scans = -1;
  int slam_domain = -1, sim_domain = -1;
  bool no_progress = false;
  double stop_after_s = 0;  // testing aid: stop (as on Ctrl-C) after this much sim time
};

class Launcher {
 public:
  Launcher(const Options& o, SwarmConfig c) : o_(o), c_(std::move(c)) {}

  // The whole run: exit status 0 (report written), 1 (a process failed) or 130 (interrupted).
  int run();

 private:
  std::string bin(const std::string& rel) const {
    const fs::path p = fs::path(o_.bin_dir) / rel;
    if (!fs::exists(p)) throw std::runtime_error(p.string() + ": missing; build first (./cdc build --preset release)");
    return fs::absolute(p).string();
  }
  // The steps of a run, in order.
  void prepare_run_folder();
  void ensure_dataset();
  void read_dataset();
  void describe_run();
  void choose_network();
  void check_local_domains() const;
  void set_up_network();
  void start_services();
  void wait_for_services();
  void start_player();
  std::string supervise();  // until the end of the run; what failed, if anything
  int finish(const std::string& failure);

  // What supervise() does on each pass.
  void read_sim_clock();
  std::string service_failure();
  std::string on_player_ended();
  void watch_rendezvous();

  Process& spawn(const std::string& name, uint32_t node, std::vector<std::string> argv,
                 std::vector<std::string> env = {});
  std::string loopback_config() const {
    return "file://" + fs::absolute(fs::path(o_.root) / "deploy/cyclonedds/loopback.xml").string();
  }
  std::string dds_config(uint32_t node) const { return net_ ? net_->dds_config(node) : loopback_config(); }
  fs::path robot_dir(uint32_t robot) const { return run_ / ("robot_" + std::to_string(robot)); }
  // Robot r's own domain: on lo in its namespace (netns) or on lo with everyone (loopback), where
  // the domain id keeps robots apart.
  uint32_t local_domain(uint32_t robot) const { return c_.local_domain_base + robot; }
  double wall_s() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }
  void apply_radio(double t_s);
  void apply_loopback_radio(double t_s);
  void apply_faults(const std::vector<uint32_t>& nodes, double t_s);
  void sample_traffic(double t_s);
  std::map<uint32_t, std::string> charge_keyframes();  // robot -> the mode its bytes are charged to
  void charge_bytes(const std::map<std::pair<uint32_t, uint32_t>, LinkBytes>& counters,
                    const std::map<uint32_t, std::string>& charged, double t_s);
  void progress(double t_s, bool final_line);
  void stop_all();
  bool interrupted() const { return stop_signal() != 0; }
  // processes.txt: every process started, "name pid", so that anyone can check none is left.
  void record_pid(const Process& p) {
    std::ofstream(run_ / "processes.txt", std::ios::app) << p.name() << ' ' << p.pid() << '\n';
  }

  Options o_;
  SwarmConfig c_;
  bool netns_ = false;
  std::string netns_unavailable_;  // why the netns mode cannot run here (auto: loopback instead)
  fs::path run_;
  std::vector<uint32_t> robots_;
  std::vector<RadioPeriod> periods_;
  std::unique_ptr<NetnsNetwork> net_;
  std::vector<std::unique_ptr<Process>> services_;  // in start order
  std::unique_ptr<Process> player_;
  RunInfo info_;
  Clock::time_point t0_ = Clock::now();
  std::map<std::pair<uint32_t, uint32_t>, LinkBytes> last_counters_;
  std::ofstream traffic_log_;                   // traffic.csv: every sample's counted bytes per robot, link and mode
  std::map<uint32_t, bool> loopback_in_range_;  // loopback radio: robot -> in range of the central
  std::map<uint32_t, uint64_t> last_keyframes_;
  std::map<uint32_t, std::string> interval_start_mode_;  // each robot's mode at the previous traffic sample
  double sim_total_s_ = 0;
  double t_s_ = 0;            // sim time now (the player's clock file)
  bool startup_ = false;      // traffic counted now belongs to start-up (discovery), not to a mode
  bool rendezvous_ = false;   // the mission is over: every link is up
  bool radio_armed_ = false;  // loopback: services are up (their signal handlers installed)
  std::optional<Rendezvous> rendezvous_watch_;
  std::optional<FaultSchedule> faults_;
  std::optional<Clock::time_point> settle_until_;  // the run ends then
};

void Launcher::ensure_dataset() {
  if (fs::exists(fs::path(c_.dataset) / "dataset.json")) return;
  if (c_.scenario.empty())
    throw std::runtime_error(c_.dataset +
                             ": no dataset there and no scenario to generate it from (a real recording: cdc-import)");
  std::cout << "cdc-launch: generating the dataset " << c_.dataset << " from " << c_.scenario << " (once)" << std::endl;
  fs::create_directories(fs::path(c_.dataset).parent_path());
  std::vector<std::string> argv = {
      bin("sim/tools/cdc-sim"), "generate", "--scenario", c_.scenario, "--out", c_.dataset};
  if (c_.max_scans > 0) argv.insert(argv.end(), {"--max-scans", std::to_string(c_.max_scans)});
  Process gen(ProcessSpec{"generate", argv, {}, "", (run_ / "logs" / "generate.log").string()});
  record_pid(gen);
  while (gen.running()) {
    if (interrupted()) {
      gen.stop(std::chrono::seconds(5));
      fs::remove_all(c_.dataset + ".partial");  // never leave half a dataset behind
      throw std::runtime_error("interrupted while generating the dataset");
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (gen.exit_status().value_or(-1) != 0) {
    fs::remove_all(c_.dataset + ".partial");
    throw std::runtime_error("dataset generation failed: see " + (run_ / "logs" / "generate.log").string());
  }
}

Process& Launcher::spawn(const std::string& name, uint32_t node, std::vector<std::string> argv,
                         std::vector<std::string> env) {
  std::string log = name;
  std::replace(log.begin(), log.end(), '/', '_');
  env.push_back("CYCLONEDDS_URI=" + dds_config(node));
  ProcessSpec spec{name, std::move(argv), std::move(env), net_ ? net_->netns(node) : "",
                   (run_ / "logs" / (log + ".log")).string()};
  services_.push_back(std::make_unique<Process>(std::move(spec)));
  record_pid(*services_.back());
  return *services_.back();
}

void Launcher::start_services() {
  const std::string slam = std::to_string(c_.slam_domain), sim = std::to_string(c_.sim_domain);
  if (info_.central) {
    spawn("central/central-optimiser", kCentralNode,
          {bin("services/central_optimiser/cdc-central-optimiser"), "--config", c_.central_config, "--domain", slam,
           "--graph-out", (run_ / "global_graph.g2o").string(), "--stats-out", (run_ / "central.stats.json").string()});
    if (c_.map) {
      spawn("central/map", kCentralNode,
            {bin("services/map/cdc-map"), "--config", c_.map_config, "--domain", slam, "--out", (run_ / "map").string(),
             "--stats-out", (run_ / "map.stats.json").string()});
    }
  }
  for (uint32_t r : robots_) {
    const std::string id = std::to_string(r);
    const fs::path rd = robot_dir(r);
    fs::create_directories(rd);
    // The robot's services talk among themselves on its own domain (on lo); descriptor, loop closure
    // and peer optimiser also join the SLAM domain, the one the radio carries.
    const std::string own = std::to_string(local_domain(r));
    const std::vector<std::string> local = {"--local-domain", own, "--local-dds-config", loopback_config()};
    std::vector<std::string> fe = {bin("services/frontend/cdc-frontend"),
                                   "--robot",
                                   id,
                                   "--config",
                                   c_.frontend_config,
                                   "--domain",
                                   own,
                                   "--dds-config",
                                   loopback_config(),
                                   "--sensor-domain",
                                   sim,
                                   "--sensor-dds-config",
                                   dds_config(r),
                                   "--trajectory-out",
                                   (rd / "odometry.tum").string(),
                                   "--stats-out",
                                   (rd / "frontend.stats.json").string()};
    if (c_.lidar_only) fe.push_back("--lidar-only");
    if (!c_.frontend_correction) fe.push_back("--no-corrections");
    if (c_.lockstep) {
      // The player sends each sweep's IMU with it and waits for the front-ends: waiting for the IMU
      // as long as it takes keeps a loaded machine from changing the odometry (runs are repeatable).
      fe.insert(fe.end(), {"--imu-wait-ms", "5000"});
    }
    spawn("robot" + id + "/frontend", r, fe);
    auto with_local = [&](std::vector<std::string> argv) {
      argv.insert(argv.end(), local.begin(), local.end());
      return argv;
    };
    spawn("robot" + id + "/descriptor", r,
          with_local({bin("services/descriptor/cdc-descriptor"), "--robot", id, "--config", c_.descriptor_config,
                      "--domain", slam, "--stats-out", (rd / "descriptor.stats.json").string()}));
    spawn("robot" + id + "/loop-closure", r,
          with_local({bin("services/loop_closure/cdc-loop-closure"), "--robot", id, "--config", c_.loop_closure_config,
                      "--domain", slam, "--stats-out", (rd / "loop_closure.stats.json").string(), "--backlog-out",
                      (rd / "loop_closure.now").string()}));
    spawn("robot" + id + "/peer-optimiser", r,
          with_local({bin("services/peer_optimiser/cdc-peer-optimiser"), "--robot", id, "--config", c_.peer_config,
                      "--domain", slam, "--mode-out", (rd / "modes.csv").string(), "--trajectory-out",
                      (rd / "keyframes.tum").string(), "--graph-out", (rd / "peer_graph.g2o").string(), "--stats-out",
                      (rd / "peer_optimiser.stats.json").string()}));
  }
}

void Launcher::apply_radio(double t_s) {
  if (!net_) {
    apply_loopback_radio(t_s);
    return;
  }
  std::vector<uint32_t> nodes = robots_;
  if (info_.central) nodes.push_back(kCentralNode);
  for (size_t i = 0; i < nodes.size(); ++i) {
    for (size_t j = i + 1; j < nodes.size(); ++j) {
      const uint32_t a = nodes[i], b = nodes[j];
      bool up = c_.variant != Variant::kSingle && (rendezvous_ || in_range(periods_, a, b, t_s));
      if (net_->link_up(a, b) != up) {
        net_->set_link(a, b, up);
        info_.links.push_back({std::chrono::duration<double>(Clock::now() - t0_).count(), t_s, a, b, up});
      }
    }
  }
  apply_faults(nodes, t_s);
}

// The swarm file's radio faults at sim time t_s (none once the mission is over: the rendezvous).
void Launcher::apply_faults(const std::vector<uint32_t>& nodes, double t_s) {
  if (c_.radio_faults.empty()) return;
  if (!faults_) faults_.emplace(c_.radio_faults, nodes);
  const std::map<DirectedPair, double> drops =
      rendezvous_ ? std::map<DirectedPair, double>{} : faults_->drops(t_s, wall_s());
  for (uint32_t src : nodes) {
    for (uint32_t dst : nodes) {
      if (src == dst) continue;
      const auto it = drops.find({src, dst});
      const double p = it == drops.end() ? 0.0 : it->second;
      const double before = net_->drop(src, dst);
      net_->set_drop(src, dst, p);
      if (net_->drop(src, dst) != before) info_.faults.push_back({wall_s(), t_s, src, dst, net_->drop(src, dst)});
    }
  }
}

// Loopback: one robot at a time. A robot out of the central's range has its SLAM domain made deaf
// and mute (SIGUSR1 to its radio-facing services; SIGUSR2 restores it), so it loses every node, not
// only the central; its own services keep talking on its local domain. Robot-to-robot periods
// cannot be applied alone.
void Launcher::apply_loopback_radio(double t_s) {
  if (!info_.central || !radio_armed_) return;
  for (uint32_t r : robots_) {
    const bool up = rendezvous_ || in_range(periods_, r, kCentralNode, t_s);
    const auto it = loopback_in_range_.try_emplace(r, true).first;
    if (it->second == up) continue;
    it->second = up;
    const std::string prefix = "robot" + std::to_string(r) + "/";
    for (auto& p : services_) {
      if (p->name().rfind(prefix, 0) != 0 || p->name() == prefix + "frontend" || !p->running()) continue;
      p->signal(up ? SIGUSR2 : SIGUSR1);
    }
    info_.links.push_back({std::chrono::duration<double>(Clock::now() - t0_).count(), t_s, r, kCentralNode, up});
  }
}

void Launcher::sample_traffic(double t_s) {
  // The counters first, then each robot's mode: the bytes counted since the previous sample are
  // charged to the mode the robot was in over that interval.
  std::map<std::pair<uint32_t, uint32_t>, LinkBytes> counters;
  if (net_) counters = net_->counters();
  charge_bytes(counters, charge_keyframes(), t_s);
}

// Each robot's mode over the interval since the previous sample, and the keyframes made in it. An
// interval in which the robot switched is charged to CENTRALIZED: around a switch the link carries the
// centralized side's traffic (keyframes until the link is cut; the backlog re-sent right after a
// rejoin), while the distributed side of it has the link down, or up for the dwell before the rejoin.
// Once the last sweep is played and the rendezvous has brought every link up, the catch-up (backlogs,
// loops that could not be closed out of range and the clouds they need) is charged to RENDEZVOUS,
// whatever the robot's mode: no keyframes are made then, and it is not the traffic of either mode at work.
std::map<uint32_t, std::string> Launcher::charge_keyframes() {
  const std::string fallback = info_.central ? "CENTRALIZED" : "DISTRIBUTED";
  std::map<uint32_t, std::string> charged, kf_charged;
  std::map<uint32_t, uint64_t> made;  // keyframes each robot made over the interval
  for (uint32_t r : robots_) {
    const RobotNow now = read_now(robot_dir(r) / "modes.csv.now");
    const std::string own = now.mode == "-" ? fallback : now.mode;
    const std::string mode = startup_ ? "STARTUP" : rendezvous_ ? "RENDEZVOUS" : own;
    auto it = interval_start_mode_.find(r);
    const bool switched =
        it != interval_start_mode_.end() && it->second != mode && it->second != "STARTUP" && mode != "RENDEZVOUS";
    charged[r] = switched ? "CENTRALIZED" : mode;
    interval_start_mode_[r] = mode;
    // Keyframes still coming out of the last sweeps in the rendezvous belong to the mode they were made in.
    kf_charged[r] = mode == "RENDEZVOUS" ? own : charged[r];
    made[r] = now.keyframes - std::min(now.keyframes, last_keyframes_[r]);
    info_.traffic[r].keyframes[kf_charged[r]] += made[r];
    last_keyframes_[r] = std::max(now.keyframes, last_keyframes_[r]);
  }
  for (uint32_t r : robots_) {
    for (uint32_t p : robots_) {
      if (p != r) info_.traffic[r].peer_keyframes[kf_charged[r]][p] += made[p];
    }
  }
  return charged;
}

// The bytes counted on each link since the previous sample, to the mode its robot is charged with.
void Launcher::charge_bytes(const std::map<std::pair<uint32_t, uint32_t>, LinkBytes>& counters,
                            const std::map<uint32_t, std::string>& charged, double t_s) {
  for (const auto& [key, b] : counters) {
    const auto [r, peer] = key;
    const std::string& mode = charged.at(r);
    LinkBytes& last = last_counters_[key];
    const LinkBytes delta{b.sent - std::min(b.sent, last.sent), b.received - std::min(b.received, last.received),
                          b.meta_sent - std::min(b.meta_sent, last.meta_sent),
                          b.meta_received - std::min(b.meta_received, last.meta_received)};
    LinkBytes& acc = info_.traffic[r].bytes[mode][peer];
    acc.sent += delta.sent;
    acc.received += delta.received;
    acc.meta_sent += delta.meta_sent;
    acc.meta_received += delta.meta_received;
    if (traffic_log_.is_open() && (delta.sent || delta.received || delta.meta_sent || delta.meta_received)) {
      traffic_log_ << std::fixed << std::setprecision(3) << wall_s() << ',' << t_s << ',' << node_name(r) << ','
                   << node_name(peer) << ',' << mode << ',' << delta.sent << ',' << delta.received << ','
                   << delta.meta_sent << ',' << delta.meta_received << ',' << (net_->link_up(r, peer) ? "up" : "down")
                   << '\n';
    }
    last = b;
  }
}

void Launcher::progress(double t_s, bool final_line) {
  std::ostringstream s;
  const double frac = sim_total_s_ > 0 ? std::clamp(t_s / sim_total_s_, 0.0, 1.0) : 0.0;
  const int width = 24, filled = static_cast<int>(frac * width);
  s << '[' << std::string(static_cast<size_t>(filled), '#') << std::string(static_cast<size_t>(width - filled), '.')
    << "] sim " << std::fixed;
  s.precision(1);
  s << t_s << '/' << sim_total_s_ << " s, wall " << std::chrono::duration<double>(Clock::now() - t0_).count() << " s";
  for (uint32_t r : robots_) {
    const RobotNow n = read_now(robot_dir(r) / "modes.csv.now");
    s << " | r" << r << ' ' << (n.mode == "-" ? "-" : n.mode.substr(0, 4)) << ' ' << n.keyframes << " kf";
  }
  if (isatty(STDOUT_FILENO)) {
    std::cout << '\r' << s.str() << "\033[K" << (final_line ? "\n" : "") << std::flush;
  } else {
    std::cout << s.str() << std::endl;
  }
}

void Launcher::stop_all() {
  if (player_) player_->stop(std::chrono::seconds(5));
  // Robots first (front-ends before back-ends), then the central node, whose final full
  // optimisation and the map's files take longest.
  for (auto it = services_.rbegin(); it != services_.rend(); ++it) {
    if ((*it)->name().rfind("central/", 0) == 0) continue;
    (*it)->signal(SIGINT);
  }
  for (auto& p : services_) {
    if (p->name().rfind("central/", 0) == 0) continue;
    if (!p->wait_for(std::chrono::seconds(20))) {
      std::cerr << "cdc-launch: " << p->name() << " (pid " << p->pid() << ") did not stop within 20 s: killed\n";
      p->stop(std::chrono::milliseconds(0));
    }
  }
  for (auto& p : services_) {
    if (p->name().rfind("central/", 0) != 0) continue;
    p->signal(SIGINT);
  }
  for (auto& p : services_) {
    if (p->name().rfind("central/", 0) != 0) continue;
    if (!p->wait_for(std::chrono::seconds(90))) {
      std::cerr << "cdc-launch: " << p->name() << " (pid " << p->pid() << ") did not stop within 90 s: killed\n";
      p->stop(std::chrono::milliseconds(0));
    }
  }
}

void Launcher::prepare_run_folder() {
  run_ = o_.out.empty() ? fs::path(o_.root) / "results" / (c_.name + "-" + timestamp()) : fs::path(o_.out);
  run_ = fs::absolute(run_).lexically_normal();
  fs::create_directories(run_ / "logs");
  fs::create_directories(run_ / "dds");
  fs::copy_file(c_.path, run_ / "swarm.yaml", fs::copy_options::overwrite_existing);
}

// The robots (robot_K folders), the radio timeline and the sim time span: the latest sweep of any
// robot (within max_scans).
void Launcher::read_dataset() {
  const fs::path dataset(c_.dataset);
  for (int r = 0; r < 255; ++r) {
    if (fs::is_directory(dataset / ("robot_" + std::to_string(r)))) robots_.push_back(static_cast<uint32_t>(r));
  }
  if (robots_.empty()) throw std::runtime_error(c_.dataset + ": no robot_K folders");
  const fs::path periods_path = dataset / "radio_periods.csv";
  if (c_.range_periods && fs::exists(periods_path)) periods_ = read_radio_periods(periods_path.string());
  for (uint32_t r : robots_) {
    std::ifstream in(dataset / ("robot_" + std::to_string(r)) / "times.txt");
    double t = 0, last = 0;
    size_t n = 0;
    while (in >> t && (c_.max_scans == 0 || n < c_.max_scans)) {
      last = t;
      ++n;
    }
    sim_total_s_ = std::max(sim_total_s_, last);
  }
}

void Launcher::describe_run() {
  info_.name = c_.name;
  info_.variant = to_string(c_.variant);
  if (c_.variant == Variant::kSwitching && !c_.frontend_correction) info_.variant = "switching-without-correction";
  info_.dataset = fs::absolute(c_.dataset).string();
  info_.run_dir = run_.string();
  info_.swarm_file = c_.path;
  info_.robots = robots_;
  info_.central = c_.variant == Variant::kSwitching;
  info_.slam_domain = c_.slam_domain;
  info_.sim_domain = c_.sim_domain;
}

void Launcher::choose_network() {
  netns_ = c_.network == NetworkMode::kNetns ||
           (c_.network == NetworkMode::kAuto && NetnsNetwork::available(&netns_unavailable_));
  if (c_.network == NetworkMode::kNetns && !NetnsNetwork::available(&netns_unavailable_)) {
    throw std::runtime_error("network: netns requested but not possible here (" + netns_unavailable_ + ")");
  }
  if (!netns_ && c_.variant != Variant::kSwitching) {
    throw std::runtime_error("variant " + std::string(to_string(c_.variant)) +
                             " needs the netns network mode (loopback cannot cut links between robots)");
  }
  if (!netns_ && !c_.radio_faults.empty()) {
    throw std::runtime_error("radio_faults need the netns network mode (loopback cannot drop single datagrams)" +
                             (netns_unavailable_.empty() ? std::string() : ": " + netns_unavailable_));
  }
  info_.network = netns_ ? "netns" : "loopback";
  info_.traffic_measured = netns_;
}

void Launcher::check_local_domains() const {
  const uint32_t last_local = local_domain(robots_.back());
  if (last_local > 232) {
    throw std::runtime_error("local_domain_base " + std::to_string(c_.local_domain_base) + " + robot id " +
                             std::to_string(robots_.back()) + " is past the last DDS domain id (232)");
  }
  for (uint32_t d : {c_.slam_domain, c_.sim_domain}) {
    if (d >= c_.local_domain_base && d <= last_local) {
      throw std::runtime_error("the robots' own domains " + std::to_string(c_.local_domain_base) + ".." +
                               std::to_string(last_local) + " (local_domain_base + robot id) include domain " +
                               std::to_string(d) + " (slam_domain or sim_domain)");
    }
  }
}

void Launcher::set_up_network() {
  if (netns_) {
    std::vector<uint32_t> nodes = robots_;
    if (info_.central) nodes.push_back(kCentralNode);
    nodes.push_back(kSimNode);
    net_ = std::make_unique<NetnsNetwork>(std::to_string(getpid()), nodes, c_.slam_domain, (run_ / "dds").string());
    {
      std::ofstream nf(run_ / "namespaces.txt");
      for (const auto& ns : net_->namespaces()) nf << ns << '\n';
    }
    traffic_log_.open(run_ / "traffic.csv");
    traffic_log_ << "wall_s,sim_s,robot,peer,mode,data_sent,data_received,discovery_sent,discovery_received,link\n";
    std::cout << "cdc-launch: network netns: " << nodes.size() << " namespaces on a private bridge (198.18.0.0/24); "
              << "the radio timeline cuts SLAM-domain traffic per pair with iptables" << std::endl;
    return;
  }
  const std::string how =
      "the radio timeline is applied per robot with DDS deaf/mute: a robot out of the central's range has its SLAM "
      "domain made deaf and mute, which cuts it from every node (robot-to-robot periods cannot be applied alone: "
      "loopback cannot cut single pairs; use netns, as root, for that); its own services keep talking on its local "
      "domain; bytes on the wire are not measured";
  info_.notes.push_back("loopback network: every process on lo; " + how);
  std::cout << "cdc-launch: network loopback (" << (netns_unavailable_.empty() ? "requested" : netns_unavailable_)
            << "): all processes on lo; " << how << std::endl;
}

// Until every peer optimiser runs and, with a central, sees it: the run starts with every robot in
// range, so each must have switched to CENTRALIZED (after its dwell) before the radio may cut a link,
// so that every later switch comes from the radio.
void Launcher::wait_for_services() {
  const auto deadline = Clock::now() + std::chrono::seconds(30);
  while (true) {
    bool ready = true;
    for (uint32_t r : robots_) {
      const fs::path now = robot_dir(r) / "modes.csv.now";
      if (!fs::exists(now)) {
        ready = false;
        continue;
      }
      const RobotNow n = read_now(now);
      if (info_.central && (!n.central_alive || n.mode != "CENTRALIZED")) ready = false;
    }
    for (auto& p : services_) {
      if (!p->running()) throw std::runtime_error(p->name() + " ended at start-up " + exit_note(*p));
    }
    if (ready) {
      radio_armed_ = true;
      return;
    }
    if (interrupted()) return;
    if (Clock::now() > deadline) {
      throw std::runtime_error(
          "the robots' peer optimisers did not come up (or did not reach CENTRALIZED with the central) "
          "within 30 s; see " +
          (run_ / "logs").string());
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
}

void Launcher::start_player() {
  std::vector<std::string> play = {bin("sim/tools/cdc-sim"),
                                   "play",
                                   c_.dataset,
                                   "--domain",
                                   std::to_string(c_.sim_domain),
                                   "--wait-readers",
                                   std::to_string(robots_.size()),
                                   "--clock-file",
                                   (run_ / "sim_clock").string()};
  if (c_.lockstep) {
    play.insert(play.end(), {"--lockstep", "--lockstep-timeout", "120"});
  } else {
    play.insert(play.end(), {"--rate", std::to_string(c_.rate)});
  }
  if (c_.max_scans > 0) play.insert(play.end(), {"--max-scans", std::to_string(c_.max_scans)});
  player_ = std::make_unique<Process>(ProcessSpec{"sim/player",
                                                  play,
                                                  {"CYCLONEDDS_URI=" + dds_config(kSimNode)},
                                                  net_ ? net_->netns(kSimNode) : "",
                                                  (run_ / "logs" / "sim_player.log").string()});
  record_pid(*player_);
}

void Launcher::read_sim_clock() {
  std::istringstream cl(read_file(run_ / "sim_clock"));
  int64_t stamp = 0;
  if (cl >> stamp) t_s_ = static_cast<double>(stamp) * 1e-9;
}

// The last service found ended, if any.
std::string Launcher::service_failure() {
  std::string failure;
  for (auto& p : services_) {
    if (!p->running()) failure = p->name() + " ended unexpectedly " + exit_note(*p);
  }
  return failure;
}

// The last sweep is played: the final rendezvous begins, or the back-ends get settle_s to finish.
std::string Launcher::on_player_ended() {
  if (player_->exit_status().value_or(-1) != 0) return "the player failed " + exit_note(*player_);
  if (c_.rendezvous_s > 0 && c_.variant != Variant::kSingle) {
    rendezvous_ = true;  // applied by apply_radio on the next pass
    rendezvous_watch_.emplace(Clock::now(), to_duration(c_.settle_s), to_duration(c_.rendezvous_s + c_.settle_s));
    std::cout << "cdc-launch: last sweep played; rendezvous: every robot back in range, up to " << c_.rendezvous_s
              << " s for all to rejoin the central, then " << c_.settle_s << " s" << std::endl;
  } else {
    settle_until_ = Clock::now() + to_duration(c_.settle_s);
  }
  return "";
}

void Launcher::watch_rendezvous() {
  std::vector<uint32_t> out, busy;
  for (uint32_t r : robots_) {
    const RobotNow n = read_now(robot_dir(r) / "modes.csv.now");
    if (n.mode != "CENTRALIZED" || n.acknowledged < n.keyframes) out.push_back(r);
    if (!loop_closure_caught_up(robot_dir(r) / "loop_closure.now")) busy.push_back(r);
  }
  Rendezvous& w = *rendezvous_watch_;
  if (!w.update(std::move(out), std::move(busy), Clock::now())) return;
  info_.rendezvous_s = w.waited_s();
  info_.not_rejoined = w.not_rejoined();
  info_.loop_closure_busy = w.loop_closure_busy();
  info_.caught_up_s = w.caught_up_s();
  if (w.not_rejoined().empty()) {
    std::cout << "cdc-launch: rendezvous: every robot CENTRALIZED and all keyframes with the central " << std::fixed
              << std::setprecision(1) << *info_.rendezvous_s << " s after the last sweep" << std::endl;
  } else {
    std::cout << "cdc-launch: rendezvous: robot(s)" << id_list(w.not_rejoined())
              << " not CENTRALIZED, or some keyframes not with the central, " << c_.rendezvous_s + c_.settle_s
              << " s after the last sweep" << std::endl;
  }
  if (!w.loop_closure_busy().empty()) {
    std::cout << "cdc-launch: rendezvous: the loop closure of robot(s)" << id_list(w.loop_closure_busy())
              << " had not caught up" << std::endl;
  }
  settle_until_ = Clock::now();
}

std::string Launcher::supervise() {
  auto last_sample = Clock::now(), last_progress = Clock::now() - std::chrono::seconds(10);
  const auto progress_period =
      isatty(STDOUT_FILENO) ? std::chrono::milliseconds(500) : std::chrono::milliseconds(10000);
  while (!interrupted()) {
    read_sim_clock();
    apply_radio(t_s_);
    if (Clock::now() - last_sample > std::chrono::milliseconds(500)) {
      sample_traffic(t_s_);
      last_sample = Clock::now();
    }
    if (!o_.no_progress && Clock::now() - last_progress > progress_period) {
      progress(t_s_, false);
      last_progress = Clock::now();
    }
    if (std::string failure = service_failure(); !failure.empty()) return failure;
    if (!settle_until_ && !rendezvous_watch_ && player_ && !player_->running()) {
      if (std::string failure = on_player_ended(); !failure.empty()) return failure;
    }
    if (rendezvous_watch_ && !settle_until_) watch_rendezvous();
    if (settle_until_ && Clock::now() >= *settle_until_) break;
    if (o_.stop_after_s > 0 && t_s_ >= o_.stop_after_s) {
      request_stop(SIGINT);  // as if Ctrl-C had been pressed now
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  return "";
}

// Stops the swarm and removes the network; then the report, unless the run failed or was interrupted.
int Launcher::finish(const std::string& failure) {
  sample_traffic(t_s_);
  if (!o_.no_progress) progress(t_s_, true);
  if (interrupted())
    std::cout << "cdc-launch: interrupted (signal " << stop_signal() << "): stopping every process" << std::endl;
  else
    std::cout << "cdc-launch: stopping the swarm" << std::endl;
  stop_all();
  if (net_) {
    if (!c_.radio_faults.empty()) info_.fault_dropped_datagrams = net_->fault_dropped();
    net_->teardown();
    net_.reset();
  }
  info_.wall_s = wall_s();
  info_.sim_end_s = t_s_;
  info_.interrupted = interrupted();
  if (!failure.empty()) {
    std::cerr << "cdc-launch: " << failure << '\n';
    return 1;
  }
  if (info_.interrupted) {
    std::cout << "cdc-launch: stopped cleanly; partial results in " << run_.string() << std::endl;
    return 130;
  }
  write_report(info_);
  std::cout << read_file(run_ / "report.md") << std::endl;
  std::cout << "cdc-launch: results in " << run_.string() << std::endl;
  return 0;
}

int Launcher::run() {
  install_stop_signals();
  prepare_run_folder();
  ensure_dataset();
  read_dataset();
  describe_run();
  choose_network();
  check_local_domains();
  set_up_network();
  std::cout << "cdc-launch: " << c_.name << ": " << robots_.size() << " robots, variant " << info_.variant << ", "
            << sim_total_s_ << " s of sim time, results in " << run_.string() << std::endl;
  apply_radio(0.0);  // the links as they are when the run starts (all cut for single robots)
  start_services();
  wait_for_services();
  // Discovery and start-up traffic is reported apart from the modes.
  startup_ = true;
  sample_traffic(0);
  startup_ = false;
  if (!interrupted()) start_player();
  return finish(supervise());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-launch: runs a swarm on a dataset (simulated, or a real recording imported with cdc-import) from a swarm "
      "file (deploy/swarms/*.yaml): the simulator's player, every\n"
      "robot's front-end, descriptor, loop-closure and peer-optimiser services and the central node's optimiser and\n"
      "map. Network modes: netns (default where possible: every node in its own network namespace, the radio\n"
      "timeline applied per pair with iptables on the SLAM domain) or loopback (all on lo, the timeline applied per\n"
      "robot by making its SLAM domain deaf and mute). Ctrl-C stops\n"
      "every process and removes every namespace. Results: results/<name>-<time>/ (report.md, report.json, plots)."};
  Options o;
  app.add_option("swarm", o.swarm, "swarm file")->required()->check(CLI::ExistingFile);
  app.add_option("--out", o.out, "results folder (default: results/<name>-<time>)");
  app.add_option("--bin-dir", o.bin_dir, "build folder holding the binaries")->capture_default_str();
  app.add_option("--root", o.root, "project root (relative paths of the swarm file)")->capture_default_str();
  app.add_option("--network", o.network, "override the swarm file: auto, netns or loopback")
      ->check(CLI::IsMember({"auto", "netns", "loopback"}));
  app.add_option("--max-scans", o.max_scans, "override: sweeps per robot (0: all)")
      ->check(cdc::config::cli_range(0, 1e6));
  app.add_option("--dataset", o.dataset,
                 "override the swarm file's dataset folder (one made by cdc-import, for example)")
      ->check(CLI::ExistingDirectory);
  app.add_option("--slam-domain", o.slam_domain, "override the SLAM DDS domain")->check(cdc::config::cli_range(0, 232));
  app.add_option("--sim-domain", o.sim_domain, "override the simulator's DDS domain")
      ->check(cdc::config::cli_range(0, 232));
  app.add_flag("--no-progress", o.no_progress, "no progress display");
  app.add_option("--stop-after", o.stop_after_s, "stop as on Ctrl-C once this much sim time has passed (testing)")
      ->check(cdc::config::cli_range(0, 1e6));
  CLI11_PARSE(app, argc, argv);
  return cdc::base::run_tool(
      "cdc-launch",
      [&] {
        SwarmConfig c = load_swarm(o.swarm, o.root);
        if (!o.network.empty()) {
          c.network = parse_network_mode(o.network).value_or(NetworkMode::kAuto);
        }
        if (o.max_scans >= 0) c.max_scans = static_cast<size_t>(o.max_scans);
        if (!o.dataset.empty()) c.dataset = o.dataset;
        if (o.slam_domain >= 0) c.slam_domain = static_cast<uint32_t>(o.slam_domain);
        if (o.sim_domain >= 0) c.sim_domain = static_cast<uint32_t>(o.sim_domain);
        if (c.slam_domain == c.sim_domain) throw cdc::config::ConfigError("the SLAM and simulator domains must differ");
        Launcher l(o, std::move(c));
        return l.run();
      },
      [](const std::exception& e) { return dynamic_cast<const cdc::config::ConfigError*>(&e) != nullptr ? 2 : 1; });
}
