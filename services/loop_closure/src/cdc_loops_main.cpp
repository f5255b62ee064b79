// cdc-loops: offline place recognition and outlier rejection tools of the loop-closure service.
#include "cdc/base/tool.hpp"
#include "cdc/config/cli_range.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/pcm.hpp"
#include "cdc/io/dataset.hpp"
#include "cdc/loop_closure/evaluation.hpp"
#include "cdc/loop_closure/loop_core.hpp"
#include "loop_config.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <random>
#include <tuple>

namespace {

using namespace cdc;

struct RunOptions {
  std::string dataset, out;
  double keyframe_m = 2.0, noise_m = 0.02, noise_rad = 0.002;
  uint64_t seed = 9;
  size_t max_scans = 0;
  bool json = false;
  loops::LoopParams params;
};

// Keyframes of a dataset, one every keyframe_m of each robot's ground truth: the cloud deskewed
// with the ground truth, odometry from the robot's previous keyframe with noise.
class DatasetKeyframes {
 public:
  explicit DatasetKeyframes(const RunOptions& o) : o_(o), rng_(o.seed), nt_(0, o.noise_m), nr_(0, o.noise_rad) {}

  // The keyframe at scan s, or nullopt when s has no ground truth or lies within keyframe_m of its
  // robot's last keyframe. `truth`: each robot's ground-truth trajectory.
  std::optional<loops::KeyframeIn> make(const io::DatasetScan& s,
                                        const std::map<uint32_t, geometry::Trajectory>& truth) {
    if (!s.truth) return std::nullopt;
    auto it = last_.find(s.robot);
    if (it != last_.end() && (it->second.translation() - s.truth->translation()).norm() < o_.keyframe_m)
      return std::nullopt;
    loops::KeyframeIn kf;
    kf.robot = s.robot;
    kf.id = next_id_[s.robot]++;
    kf.T_odom = *s.truth;  // a levelled odometry's tilt: the truth's (world z is up)
    kf.cloud = deskewed_cloud(s, truth.at(s.robot));
    if (it != last_.end()) {
      kf.T_prev = it->second.inverse() * (*s.truth) * noise();
    }
    const double st = std::max(o_.noise_m, 1e-3), sr = std::max(o_.noise_rad, 1e-4);
    kf.information.diagonal() << 1 / (st * st), 1 / (st * st), 1 / (st * st), 1 / (sr * sr), 1 / (sr * sr),
        1 / (sr * sr);
    last_[s.robot] = *s.truth;
    return kf;
  }

 private:
  // The sweep's points in the keyframe's frame (the sensor's pose at the sweep start), each moved by
  // the ground truth's motion until its own time.
  static std::vector<Eigen::Vector3f> deskewed_cloud(const io::DatasetScan& s, const geometry::Trajectory& traj) {
    std::vector<Eigen::Vector3f> cloud;
    const Eigen::Isometry3d T0_inv = s.truth->inverse();
    for (const io::CloudPoint& p : io::read_dataset_scan(s).points) {
      const auto Tt = geometry::interpolate_at(traj, s.stamp_ns + static_cast<int64_t>(p.time_offset * 1e9));
      const Eigen::Vector3d q =
          Tt ? Eigen::Vector3d(T0_inv * (*Tt) * Eigen::Vector3d(p.x, p.y, p.z)) : Eigen::Vector3d(p.x, p.y, p.z);
      cloud.push_back(q.cast<float>());
    }
    return cloud;
  }

  Eigen::Isometry3d noise() {
    Eigen::Isometry3d noise = Eigen::Isometry3d::Identity();
    noise.translation() = Eigen::Vector3d(nt_(rng_), nt_(rng_), nt_(rng_));
    noise.linear() = (Eigen::AngleAxisd(nr_(rng_), Eigen::Vector3d::UnitZ()) *
                      Eigen::AngleAxisd(nr_(rng_), Eigen::Vector3d::UnitY()) *
                      Eigen::AngleAxisd(nr_(rng_), Eigen::Vector3d::UnitX()))
                         .toRotationMatrix();
    return noise;
  }

  const RunOptions& o_;
  std::mt19937_64 rng_;
  std::normal_distribution<double> nt_, nr_;
  std::map<uint32_t, Eigen::Isometry3d> last_;
  std::map<uint32_t, uint32_t> next_id_;
};

// The loops standing at the end: accepted and not withdrawn since.
class StandingLoops {
 public:
  void apply(const std::vector<loops::LoopOut>& events) {
    for (const loops::LoopOut& l : events) {
      const auto key = std::make_tuple(l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b);
      if (l.withdrawn)
        standing_.erase(key);
      else
        standing_[key] = l;
    }
  }
  std::vector<loops::LoopOut> list() const {
    std::vector<loops::LoopOut> out;
    for (const auto& [k, l] : standing_) out.push_back(l);
    return out;
  }

 private:
  std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>, loops::LoopOut> standing_;
};

nlohmann::json run_report(const RunOptions& o, size_t keyframes, size_t accepted, const loops::LoopEvaluation& ev,
                          const loops::LoopStats& st, double run_s) {
  return {{"dataset", o.dataset},
          {"keyframes", keyframes},
          {"accepted", accepted},
          {"true_positives", ev.true_positives},
          {"false_intra", ev.false_intra},
          {"false_inter", ev.false_inter},
          {"precision", ev.precision()},
          {"revisits", ev.revisits},
          {"recalled", ev.recalled},
          {"recall", ev.recall()},
          {"verified", st.verified},
          {"verification_failed", st.verification_failed},
          {"clouds_prepared", st.prepared},
          {"prepared_clouds_reused", st.prepared_reused},
          {"intra_inconsistent", st.intra_inconsistent},
          {"withdrawn", st.withdrawn},
          {"run_s", run_s}};
}

void write_loops_csv(const std::filesystem::path& path, const loops::LoopEvaluation& ev) {
  std::ofstream csv(path);
  csv << "robot_a,keyframe_a,robot_b,keyframe_b,tx,ty,tz,qx,qy,qz,qw,fitness,correct,error_m,error_deg\n";
  for (const auto& v : ev.loops) {
    const Eigen::Quaterniond q(v.loop.T_a_b.rotation());
    const Eigen::Vector3d t = v.loop.T_a_b.translation();
    csv << v.loop.robot_a << ',' << v.loop.keyframe_a << ',' << v.loop.robot_b << ',' << v.loop.keyframe_b << ','
        << t.x() << ',' << t.y() << ',' << t.z() << ',' << q.x() << ',' << q.y() << ',' << q.z() << ',' << q.w() << ','
        << v.loop.fitness << ',' << (v.correct ? 1 : 0) << ',' << v.error_m << ',' << v.error_deg << '\n';
  }
}

// The loop-closure core as one robot's service would run it, with every cloud at hand, over the
// dataset's keyframes; the loops standing at the end judged against the ground truth.
int run_dataset(const RunOptions& o) {
  std::map<uint32_t, geometry::Trajectory> gt;
  const std::vector<io::DatasetScan> scans = io::list_dataset_scans(o.dataset, o.max_scans, &gt);
  DatasetKeyframes keyframes(o);
  loops::LoopCore core(o.params);
  std::vector<loops::TruthKeyframe> order;
  StandingLoops standing;
  std::ofstream kf_csv;
  if (!o.out.empty()) {
    std::filesystem::create_directories(o.out);
    kf_csv.open(std::filesystem::path(o.out) / "keyframes.csv");
    kf_csv << "robot,keyframe,stamp_ns,scan\n";
  }
  const auto t0 = std::chrono::steady_clock::now();
  for (const io::DatasetScan& s : scans) {
    std::optional<loops::KeyframeIn> kf = keyframes.make(s, gt);
    if (!kf) continue;
    order.push_back({s.robot, kf->id, *s.truth});
    if (kf_csv) kf_csv << s.robot << ',' << kf->id << ',' << s.stamp_ns << ',' << s.seq << '\n';
    standing.apply(core.add_keyframe(std::move(*kf)));
  }
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::vector<loops::LoopOut> accepted = standing.list();
  loops::EvaluationOptions eo;
  eo.exclude_recent = o.params.exclude_recent;
  const loops::LoopEvaluation ev = loops::evaluate_loops(order, accepted, eo);
  const nlohmann::json report = run_report(o, order.size(), accepted.size(), ev, core.stats(), run_s);
  if (!o.out.empty()) {
    write_loops_csv(std::filesystem::path(o.out) / "loops.csv", ev);
    std::ofstream(std::filesystem::path(o.out) / "report.json") << report.dump(2) << '\n';
  }
  if (o.json) {
    std::cout << report.dump() << '\n';
  } else {
    std::printf(
        "%s: %zu keyframes, %zu loops accepted (%zu true): precision %.3f, recall %.3f of %zu revisits, %.1f s\n",
        o.dataset.c_str(), order.size(), accepted.size(), ev.true_positives, ev.precision(), ev.recall(), ev.revisits,
        run_s);
  }
  return 0;
}

struct PcmCommand {
  std::string input;
  bool json = false, strict = false;
  double threshold = graph::PcmOptions{}.chi2_threshold;
};

// PCM over a multi-robot g2o folder (or one file): which inter-robot loops to keep.
int run_pcm(const PcmCommand& c) {
  std::vector<std::string> warnings;
  graph::G2oReadOptions ro;
  graph::G2oReadReport report;
  ro.skip_malformed = !c.strict;
  ro.warnings = &warnings;
  ro.report = &report;
  const graph::PoseGraph g =
      std::filesystem::is_directory(c.input) ? graph::read_g2o_folder(c.input, ro) : graph::read_g2o(c.input, ro);
  for (const auto& w : warnings) {
    std::cerr << "cdc-loops: warning: " << w << '\n';
  }
  graph::PcmOptions po;
  po.chi2_threshold = c.threshold;
  const graph::OutlierDecision d = graph::Pcm(po).decide(g);
  auto ids = [&](const std::vector<size_t>& factors) {
    nlohmann::json a = nlohmann::json::array();
    for (size_t f : factors) {
      a.push_back({graph::to_g2o_key(g, g.factors[f].a), graph::to_g2o_key(g, g.factors[f].b)});
    }
    return a;
  };
  if (c.json) {
    nlohmann::json j{{"accepted", ids(d.accepted)},
                     {"rejected", ids(d.rejected)},
                     // Lines whose record is not in the graph: malformed ones and second listings of an edge.
                     {"skipped_lines", report.skipped_lines + report.duplicate_edges},
                     {"malformed_lines", report.skipped_lines},
                     {"duplicate_edges", report.duplicate_edges},
                     {"parallel_edges", report.parallel_edges},
                     {"chi2_threshold", c.threshold}};
    std::cout << j.dump() << '\n';
  } else {
    std::cout << c.input << ": " << d.accepted.size() << " inter-robot loop closures kept, " << d.rejected.size()
              << " rejected (chi2 " << c.threshold << ")\n";
  }
  return 0;
}

void add_pcm_command(CLI::App& app, PcmCommand& c) {
  CLI::App* pcm = app.add_subcommand("pcm", "run PCM over a multi-robot g2o folder (or one g2o file)");
  pcm->add_option("input", c.input, "folder of per-robot .g2o files, or one .g2o file")
      ->required()
      ->check(CLI::ExistingPath);
  cdc::config::add_number_option(*pcm, "--chi2", c.threshold, "Mahalanobis threshold on a cycle (6 DoF)", 0.01, 1e6);
  pcm->add_flag("--json", c.json, "print one JSON object with the accepted and rejected loops (g2o vertex ids)");
  pcm->add_flag("--strict", c.strict, "fail on damaged lines instead of skipping them");
}

// `run`'s options: the core's parameters from --config (or built in), --chi2 and --min-support over them.
struct RunCommand {
  RunOptions run;
  std::string config;
  double chi2 = RunOptions{}.params.pcm.chi2_threshold;
  size_t support = RunOptions{}.params.min_inter_support;
  CLI::Option* chi2_given = nullptr;
  CLI::Option* support_given = nullptr;

  RunOptions resolved() const {
    RunOptions o = run;
    if (!config.empty()) o.params = loops::load_loop_options(config).core;
    if (chi2_given->count() > 0 || config.empty()) o.params.pcm.chi2_threshold = chi2;
    if (support_given->count() > 0 || config.empty()) o.params.min_inter_support = support;
    return o;
  }
};

CLI::App* add_run_command(CLI::App& app, RunCommand& c) {
  RunOptions& o = c.run;
  CLI::App* run = app.add_subcommand(
      "run",
      "loop closure over a cdc-sim dataset folder, judged against its ground truth.\n"
      "Splits whose robots revisit places driving the other way: cdc-sim generate --scenario\n"
      "sim/scenarios/kitti08_3robots.yaml (08's own loops are driven in reverse), kitti05_3robots_reverse.yaml or\n"
      "kitti00_3robots_reverse.yaml (robot 1 drives its piece backwards on the opposite lane: trajectories.reverse)");
  run->add_option("dataset", o.dataset, "dataset folder (cdc-sim generate)")->required()->check(CLI::ExistingDirectory);
  run->add_option("--out", o.out, "write keyframes.csv, loops.csv and report.json here");
  cdc::config::add_number_option(*run, "--keyframe-m", o.keyframe_m, "keyframe every this far [m]", 0.01, 1000);
  cdc::config::add_number_option(*run, "--noise-m", o.noise_m, "odometry noise per keyframe, translation sigma [m]", 0,
                                 10);
  cdc::config::add_number_option(*run, "--noise-rad", o.noise_rad, "odometry noise per keyframe, rotation sigma [rad]",
                                 0, 1);
  cdc::config::add_number_option(*run, "--seed", o.seed, "noise seed", 0, 4294967295);
  cdc::config::add_number_option(*run, "--max-scans", o.max_scans, "scans per robot (0: all)", 0, 1e6);
  run->add_option(
         "--config", c.config,
         "the service's configuration (services/loop_closure/config/loop_closure.yaml) for the core's parameters;\n"
         "default: their built-in defaults. --chi2 and --min-support override it")
      ->check(CLI::ExistingFile);
  c.chi2_given = cdc::config::add_number_option(*run, "--chi2", c.chi2, "PCM threshold", 0.01, 1e6);
  c.support_given = cdc::config::add_number_option(
      *run, "--min-support", c.support, "inter-robot loops are published from a PCM-consistent set at least this large",
      1, 1000);
  run->add_flag("--json", o.json, "print the report as one JSON object");
  return run;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "cdc-loops: offline tools of the loop-closure service.\n"
      "  run DATASET  descriptors, retrieval, verification and PCM over a cdc-sim dataset folder (keyframes from its\n"
      "               ground truth, odometry with noise), with precision and recall against the ground truth\n"
      "  pcm DIR   pairwise consistency maximisation over a multi-robot g2o folder (one file per robot, robot in\n"
      "            the top byte of the keys): which inter-robot loop closures to keep"};
  app.require_subcommand(1);
  PcmCommand pcm;
  add_pcm_command(app, pcm);
  RunCommand run;
  const CLI::App* run_app = add_run_command(app, run);
  CLI11_PARSE(app, argc, argv);
  return cdc::base::run_tool("cdc-loops",
                             [&] { return run_app->parsed() ? run_dataset(run.resolved()) : run_pcm(pcm); });
}
