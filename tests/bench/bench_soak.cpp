// cdc-bench-soak: a long mission of the back-ends. Starts, as its own child processes, the central
// optimiser, one peer optimiser per robot and the swarm feeder (simulated laps, so that loop closures
// keep coming), lets the feeder stream for --minutes, and every --sample-s samples each child's
// resident memory (VmRSS) and CPU time (utime + stime) and the central's keyframe count (from its
// acknowledgements). Writes one CSV row per sample and reports each service's resident memory at
// the middle and the end and its slope over the last 30 minutes (least squares), the central's CPU
// seconds per keyframe in the first and the last ten minutes, and the feeder's memory growth per
// keyframe. Runs with a loopback Cyclone configuration (CYCLONEDDS_URI or --dds-config). Last
// output line: one JSON object.
#include "cdc/dds/participant.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/qos.hpp"
#include "cdc/dds/shutdown.hpp"
#include "cdc/dds/topics.hpp"
#include "child_process.hpp"
#include "least_squares.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <unistd.h>
#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

struct Options {
  double minutes = 60;
  uint32_t robots = 3;
  double rate_hz = 1;
  double sample_s = 10;
  std::string out_dir;
  std::string dds_config;
  std::string central_bin = CDC_CENTRAL_BIN, peer_bin = CDC_PEER_BIN, feeder_bin = CDC_FEEDER_BIN;
  std::vector<std::string> feeder_args;
};

struct Service {
  std::string name;
  cdc::test::ChildProcess process;
};

struct Usage {
  double rss_mb = 0;
  double cpu_s = 0;
};

struct Sample {
  double t_s = 0;
  int64_t central_keyframes = 0;
  std::vector<Usage> usage;  // per service
};

// VmRSS and utime + stime of a process, from /proc; false once the process is gone.
bool read_usage(pid_t pid, Usage& u) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  bool found = false;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) {
      u.rss_mb = std::stod(line.substr(6)) / 1024.0;
      found = true;
    }
  }
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string text((std::istreambuf_iterator<char>(stat)), std::istreambuf_iterator<char>());
  const size_t close = text.rfind(')');
  if (!found || close == std::string::npos) return false;
  std::istringstream rest(text.substr(close + 1));
  std::string field;
  double utime = 0, stime = 0;
  for (int i = 3; i <= 15 && rest >> field; ++i) {  // fields 14 and 15 (utime, stime) in clock ticks
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  u.cpu_s = (utime + stime) / static_cast<double>(::sysconf(_SC_CLK_TCK));
  return true;
}

// The sample nearest to time t.
const Sample& at(const std::vector<Sample>& s, double t) {
  return *std::min_element(s.begin(), s.end(),
                           [t](const Sample& a, const Sample& b) { return std::abs(a.t_s - t) < std::abs(b.t_s - t); });
}

std::string write_file(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
  return p.string();
}

std::vector<Service> start_services(const Options& o, const fs::path& dir) {
  const std::string robots = std::to_string(o.robots);
  const std::string central_cfg = write_file(dir / "central.yaml", "robots: " + robots + "\n");
  const std::string peer_cfg = write_file(dir / "peer.yaml", "robots: " + robots + "\nrange_m: 1.0e6\n");
  std::vector<Service> s;
  s.push_back({"central", cdc::test::ChildProcess::spawn(
                              {o.central_bin, "--config", central_cfg, "--stats-out", (dir / "central.json").string()},
                              (dir / "central.log").string())});
  for (uint32_t r = 0; r < o.robots; ++r) {
    const std::string name = "peer" + std::to_string(r);
    s.push_back({name, cdc::test::ChildProcess::spawn({o.peer_bin, "--robot", std::to_string(r), "--config", peer_cfg,
                                                       "--stats-out", (dir / (name + ".json")).string()},
                                                      (dir / (name + ".log")).string())});
  }
  std::vector<std::string> feeder = {o.feeder_bin,
                                     "--robots",
                                     robots,
                                     "--keyframes",
                                     "0",
                                     "--minutes",
                                     std::to_string(o.minutes),
                                     "--rate-hz",
                                     std::to_string(o.rate_hz),
                                     "--wait-readers",
                                     std::to_string(o.robots + 1)};
  feeder.insert(feeder.end(), o.feeder_args.begin(), o.feeder_args.end());
  s.push_back({"feeder", cdc::test::ChildProcess::spawn(feeder, (dir / "feeder.log").string())});
  return s;
}

// SIGTERM each still running child (the central optimises fully and writes its stats), SIGKILL after
// the timeout.
void stop_services(std::vector<Service>& services) {
  for (auto& s : services) s.process.signal(SIGTERM);
  for (auto& s : services) {
    if (s.process.running() && !s.process.wait(std::chrono::seconds(120))) {
      std::fprintf(stderr, "cdc-bench-soak: %s did not stop within 120 s; killed\n", s.name.c_str());
      s.process.signal(SIGKILL);
      s.process.wait(std::chrono::seconds(5));
    }
  }
}

// Keyframes the central holds (contiguous from 0, summed over the robots), from its acknowledgements.
class CentralKeyframes {
 public:
  explicit CentralKeyframes(cdc::dds::Participant& p)
      : topic_(p, cdc::dds::topics::kCentralAck), reader_(p, topic_, cdc::dds::qos::keyed_state()) {}
  int64_t count() {
    reader_.take(256).for_each_valid([&](const cdc_msg_Acknowledgement& m, const dds_sample_info_t&) {
      highest_[m.robot_id] = m.highest_contiguous_keyframe;
    });
    int64_t n = 0;
    for (const auto& [robot, h] : highest_) n += h + 1;
    return n;
  }

 private:
  cdc::dds::Topic<cdc_msg_Acknowledgement> topic_;
  cdc::dds::Reader<cdc_msg_Acknowledgement> reader_;
  std::map<uint32_t, int64_t> highest_;
};

std::string csv_header(const std::vector<Service>& services) {
  std::string h = "t_s,central_keyframes";
  for (const auto& s : services) h += "," + s.name + "_rss_mb," + s.name + "_cpu_s";
  return h;
}

std::string csv_row(const Sample& s) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.1f,%lld", s.t_s, static_cast<long long>(s.central_keyframes));
  std::string row = buf;
  for (const Usage& u : s.usage) {
    std::snprintf(buf, sizeof buf, ",%.3f,%.2f", u.rss_mb, u.cpu_s);
    row += buf;
  }
  return row;
}

// Samples every sample_s until the run's minutes have passed (the feeder then stops by itself) or a
// service ends early (false).
bool sample_run(const Options& o, std::vector<Service>& services, CentralKeyframes& central, std::ostream& csv,
                std::vector<Sample>& samples) {
  const auto start = Clock::now();
  const auto period = std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(o.sample_s));
  for (auto next = start; !cdc::dds::ShutdownSignal::requested(); next += period) {
    std::this_thread::sleep_until(next);
    Sample s;
    s.t_s = std::chrono::duration<double>(Clock::now() - start).count();
    s.central_keyframes = central.count();
    for (auto& svc : services) {
      Usage u;
      if (!read_usage(svc.process.pid(), u)) {  // a process that ended has no VmRSS
        if (svc.name == "feeder" && s.t_s >= o.minutes * 60) return true;
        std::fprintf(stderr, "cdc-bench-soak: %s ended early, at %.0f s\n", svc.name.c_str(), s.t_s);
        return false;
      }
      s.usage.push_back(u);
    }
    csv << csv_row(s) << '\n' << std::flush;
    samples.push_back(s);
    if (s.t_s >= o.minutes * 60) return true;
  }
  return false;
}

// Samples within [t0, t1].
std::vector<const Sample*> window(const std::vector<Sample>& s, double t0, double t1) {
  std::vector<const Sample*> w;
  for (const Sample& x : s) {
    if (x.t_s >= t0 - 1e-6 && x.t_s <= t1 + 1e-6) w.push_back(&x);
  }
  return w;
}

// The central's CPU seconds per keyframe between two samples.
double cpu_per_keyframe(const Sample& a, const Sample& b) {
  const double kf = static_cast<double>(b.central_keyframes - a.central_keyframes);
  return kf > 0 ? (b.usage[0].cpu_s - a.usage[0].cpu_s) / kf : 0;
}

nlohmann::json service_figures(const std::vector<Sample>& samples, size_t i, double end_s, double tail_s) {
  std::vector<double> t, rss;
  for (const Sample* s : window(samples, end_s - tail_s, end_s)) {
    t.push_back(s->t_s);
    rss.push_back(s->usage[i].rss_mb);
  }
  const double mb_per_30min = cdc::test::slope(t, rss) * 1800.0;
  return {{"rss_mb_mid", at(samples, end_s / 2).usage[i].rss_mb},
          {"rss_mb_end", samples.back().usage[i].rss_mb},
          {"rss_slope_mb_per_30min", mb_per_30min},
          {"rss_growth_mb_over_tail", mb_per_30min * tail_s / 1800.0},
          {"cpu_s_end", samples.back().usage[i].cpu_s}};
}

// The feeder's resident memory growth per keyframe (least squares over the samples after the first minute).
double feeder_kb_per_keyframe(const std::vector<Sample>& samples, size_t feeder) {
  std::vector<double> kf, rss;
  for (const Sample& s : samples) {
    if (s.t_s < std::min(60.0, samples.back().t_s / 4)) continue;
    kf.push_back(static_cast<double>(s.central_keyframes));
    rss.push_back(s.usage[feeder].rss_mb * 1024.0);
  }
  return cdc::test::slope(kf, rss);
}

nlohmann::json report(const Options& o, const std::vector<Service>& services, const std::vector<Sample>& samples) {
  const double end_s = samples.back().t_s;
  const double tail_s = std::min(1800.0, end_s / 2);  // the last 30 minutes (half of a shorter run)
  const double ten_s = std::min(600.0, end_s / 3);    // ten minutes (a third of a shorter run)
  nlohmann::json j = {{"minutes", o.minutes},
                      {"robots", o.robots},
                      {"rate_hz", o.rate_hz},
                      {"samples", samples.size()},
                      {"tail_s", tail_s},
                      {"ten_s", ten_s},
                      {"central_keyframes", samples.back().central_keyframes}};
  bool rss_ok = true;
  for (size_t i = 0; i < services.size(); ++i) {
    j["services"][services[i].name] = service_figures(samples, i, end_s, tail_s);
    rss_ok = rss_ok && j["services"][services[i].name]["rss_growth_mb_over_tail"].get<double>() < 10.0;
  }
  const auto first = window(samples, 0, ten_s), last = window(samples, end_s - ten_s, end_s);
  const double cpu_first = cpu_per_keyframe(*first.front(), *first.back());
  const double cpu_last = cpu_per_keyframe(*last.front(), *last.back());
  j["central_cpu_ms_per_keyframe_first"] = cpu_first * 1e3;
  j["central_cpu_ms_per_keyframe_last"] = cpu_last * 1e3;
  j["central_cpu_per_keyframe_ratio"] = cpu_first > 0 ? cpu_last / cpu_first : 0;
  j["feeder_kb_per_keyframe"] = feeder_kb_per_keyframe(samples, services.size() - 1);
  j["rss_ok"] = rss_ok;
  j["cpu_ok"] = cpu_first > 0 && cpu_last < 2 * cpu_first;
  return j;
}

void print_summary(const nlohmann::json& j) {
  for (const auto& [name, f] : j["services"].items()) {
    std::printf("%-8s RSS %.1f MB at %.0f min, %.1f MB at %.0f min; slope over the last %.0f min %+.2f MB per 30 min\n",
                name.c_str(), f["rss_mb_mid"].get<double>(), j["minutes"].get<double>() / 2,
                f["rss_mb_end"].get<double>(), j["minutes"].get<double>(), j["tail_s"].get<double>() / 60,
                f["rss_slope_mb_per_30min"].get<double>());
  }
  std::printf("central  CPU per keyframe: %.2f ms in the first %.0f min, %.2f ms in the last (ratio %.2f)\n",
              j["central_cpu_ms_per_keyframe_first"].get<double>(), j["ten_s"].get<double>() / 60,
              j["central_cpu_ms_per_keyframe_last"].get<double>(), j["central_cpu_per_keyframe_ratio"].get<double>());
  std::printf("feeder   RSS growth %.2f KB per keyframe (%lld keyframes)\n", j["feeder_kb_per_keyframe"].get<double>(),
              static_cast<long long>(j["central_keyframes"].get<int64_t>()));
}

// Lines of a log that contain `text` (a peer's mode switches: the central's liveliness lapsed).
size_t count_lines(const fs::path& path, const std::string& text) {
  std::ifstream in(path);
  size_t n = 0;
  for (std::string line; std::getline(in, line);)
    if (line.find(text) != std::string::npos) ++n;
  return n;
}

// What the services' own logs and stats say: the peers' switches to DISTRIBUTED (the central's
// liveliness lapsed) and the central's final graph and update counts.
void add_run_facts(const Options& o, const fs::path& dir, nlohmann::json& j) {
  for (uint32_t r = 0; r < o.robots; ++r) {
    j["peer_switches_to_distributed"].push_back(
        count_lines(dir / ("peer" + std::to_string(r) + ".log"), "CENTRALIZED -> DISTRIBUTED"));
  }
  std::ifstream stats(dir / "central.json");  // written by the central as it stops
  if (stats) {
    const nlohmann::json c = nlohmann::json::parse(stats, nullptr, false);
    for (const char* key :
         {"graph_poses", "graph_factors", "loops_accepted", "updates", "unsettled_updates", "results_held"}) {
      if (c.is_object() && c.contains(key)) j["central_stats"][key] = c[key];
    }
  }
}

int run(const Options& o) {
  if (!o.dds_config.empty()) ::setenv("CYCLONEDDS_URI", ("file://" + o.dds_config).c_str(), 1);
  if (std::getenv("CYCLONEDDS_URI") == nullptr) {
    std::cerr << "cdc-bench-soak: set CYCLONEDDS_URI or --dds-config (deploy/cyclonedds/loopback.xml)\n";
    return 2;
  }
  const fs::path dir =
      o.out_dir.empty() ? fs::temp_directory_path() / ("cdc_soak_" + std::to_string(::getpid())) : fs::path(o.out_dir);
  fs::create_directories(dir);
  cdc::dds::ParticipantOptions po;
  po.domain_id = cdc::dds::domain_from_env(0);
  cdc::dds::Participant participant(po);
  CentralKeyframes central(participant);
  std::vector<Service> services = start_services(o, dir);
  std::ofstream csv(dir / "soak.csv");
  csv << csv_header(services) << '\n';
  std::vector<Sample> samples;
  const bool complete = sample_run(o, services, central, csv, samples);
  stop_services(services);
  std::printf("soak: %zu samples in %s (logs and soak.csv)\n", samples.size(), dir.c_str());
  if (samples.size() < 4) {
    std::cerr << "cdc-bench-soak: too few samples\n";
    return 1;
  }
  nlohmann::json j = report(o, services, samples);
  j["complete"] = complete;
  add_run_facts(o, dir, j);
  j["csv"] = (dir / "soak.csv").string();
  print_summary(j);
  std::cout << j.dump() << std::endl;
  return complete ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  cdc::dds::ShutdownSignal::install();
  CLI::App app{"cdc-bench-soak: a long back-end mission; resident memory and CPU of every service over time"};
  Options o;
  app.add_option("--minutes", o.minutes, "how long the feeder streams")
      ->capture_default_str()
      ->check(CLI::Range(0.5, 1440.0));
  app.add_option("--robots", o.robots)->capture_default_str()->check(CLI::Range(1, 26));
  app.add_option("--rate-hz", o.rate_hz, "keyframes per second per robot")
      ->capture_default_str()
      ->check(CLI::Range(0.05, 100.0));
  app.add_option("--sample-s", o.sample_s, "sampling period [s]")->capture_default_str()->check(CLI::Range(0.5, 600.0));
  app.add_option("--out-dir", o.out_dir, "logs and soak.csv (default: a new temporary directory)");
  app.add_option("--dds-config", o.dds_config, "Cyclone configuration file (default: CYCLONEDDS_URI)");
  app.add_option("--central-bin", o.central_bin)->capture_default_str();
  app.add_option("--peer-bin", o.peer_bin)->capture_default_str();
  app.add_option("--feeder-bin", o.feeder_bin)->capture_default_str();
  app.add_option("--feeder-arg", o.feeder_args, "extra feeder argument (repeatable; e.g. --feeder-arg=--seed=2)");
  CLI11_PARSE(app, argc, argv);
  try {
    return run(o);
  } catch (const std::exception& e) {
    std::cerr << "cdc-bench-soak: " << e.what() << '\n';
    return 1;
  }
}
