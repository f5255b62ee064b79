// cdc-loops: offline place recognition and outlier rejection tools of the loop-closure service.
#include "cdc/graph/g2o.hpp"
#include "cdc/io/dataset.hpp"
#include "cdc/graph/pcm.hpp"
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
#include <random>

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

// Keyframes every keyframe_m of ground truth, clouds deskewed with the ground truth, odometry
// between keyframes with noise; then the loop-closure core as one robot's service would run it,
// with every cloud at hand, and the loops standing at the end judged against the ground truth.
int run_dataset(const RunOptions& o) {
  std::map<uint32_t, geometry::Trajectory> gt;
  const std::vector<io::DatasetScan> scans = io::list_dataset_scans(o.dataset, o.max_scans, &gt);
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<double> nt(0, o.noise_m), nr(0, o.noise_rad);
  loops::LoopCore core(o.params);
  std::map<uint32_t, Eigen::Isometry3d> last;
  std::map<uint32_t, uint32_t> next_id;
  std::vector<loops::TruthKeyframe> order;
  std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>, loops::LoopOut> standing;
  std::ofstream kf_csv;
  if (!o.out.empty()) {
    std::filesystem::create_directories(o.out);
    kf_csv.open(std::filesystem::path(o.out) / "keyframes.csv");
    kf_csv << "robot,keyframe,stamp_ns,scan\n";
  }
  const auto t0 = std::chrono::steady_clock::now();
  for (const io::DatasetScan& s : scans) {
    if (!s.truth) continue;
    auto it = last.find(s.robot);
    if (it != last.end() && (it->second.translation() - s.truth->translation()).norm() < o.keyframe_m) continue;
    const geometry::Trajectory& traj = gt.at(s.robot);
    loops::KeyframeIn kf;
    kf.robot = s.robot;
    kf.id = next_id[s.robot]++;
    kf.T_odom = *s.truth;  // a levelled odometry's tilt: the truth's (world z is up)
    const Eigen::Isometry3d T0_inv = s.truth->inverse();
    for (const io::CloudPoint& p : io::read_dataset_scan(s).points) {
      const auto Tt = geometry::interpolate_at(traj, s.stamp_ns + static_cast<int64_t>(p.time_offset * 1e9));
      const Eigen::Vector3d q = Tt ? Eigen::Vector3d(T0_inv * (*Tt) * Eigen::Vector3d(p.x, p.y, p.z))
                                   : Eigen::Vector3d(p.x, p.y, p.z);
      kf.cloud.push_back(q.cast<float>());
    }
    if (it != last.end()) {
      Eigen::Isometry3d noise = Eigen::Isometry3d::Identity();
      noise.translation() = Eigen::Vector3d(nt(rng), nt(rng), nt(rng));
      noise.linear() = (Eigen::AngleAxisd(nr(rng), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(nr(rng), Eigen::Vector3d::UnitY()) *
                        Eigen::AngleAxisd(nr(rng), Eigen::Vector3d::UnitX())).toRotationMatrix();
      kf.T_prev = it->second.inverse() * (*s.truth) * noise;
    }
    const double st = std::max(o.noise_m, 1e-3), sr = std::max(o.noise_rad, 1e-4);
    kf.information.diagonal() << 1 / (st * st), 1 / (st * st), 1 / (st * st), 1 / (sr * sr), 1 / (sr * sr), 1 / (sr * sr);
    last[s.robot] = *s.truth;
    order.push_back({s.robot, kf.id, *s.truth});
    if (kf_csv) kf_csv << s.robot << ',' << kf.id << ',' << s.stamp_ns << ',' << s.seq << '\n';
    for (const loops::LoopOut& l : core.add_keyframe(std::move(kf))) {
      const auto key = std::make_tuple(l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b);
      if (l.withdrawn) standing.erase(key);
      else standing[key] = l;
    }
  }
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::vector<loops::LoopOut> accepted;
  for (const auto& [k, l] : standing) accepted.push_back(l);
  loops::EvaluationOptions eo;
  eo.exclude_recent = o.params.exclude_recent;
  const loops::LoopEvaluation ev = loops::evaluate_loops(order, accepted, eo);
  const loops::LoopStats& st = core.stats();
  nlohmann::json report{{"dataset", o.dataset},
                        {"keyframes", order.size()},
                        {"accepted", accepted.size()},
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
  if (!o.out.empty()) {
    std::ofstream csv(std::filesystem::path(o.out) / "loops.csv");
    csv << "robot_a,keyframe_a,robot_b,keyframe_b,tx,ty,tz,qx,qy,qz,qw,fitness,correct,error_m,error_deg\n";
    for (const auto& v : ev.loops) {
      const Eigen::Quaterniond q(v.loop.T_a_b.rotation());
      const Eigen::Vector3d t = v.loop.T_a_b.translation();
      csv << v.loop.robot_a << ',' << v.loop.keyframe_a << ',' << v.loop.robot_b << ',' << v.loop.keyframe_b << ',' << t.x()
          << ',' << t.y() << ',' << t.z() << ',' << q.x() << ',' << q.y() << ',' << q.z() << ',' << q.w() << ','
          << v.loop.fitness << ',' << (v.correct ? 1 : 0) << ',' << v.error_m << ',' << v.error_deg << '\n';
    }
    std::ofstream(std::filesystem::path(o.out) / "report.json") << report.dump(2) << '\n';
  }
  if (o.json) {
    std::cout << report.dump() << '\n';
  } else {
    std::printf("%s: %zu keyframes, %zu loops accepted (%zu true): precision %.3f, recall %.3f of %zu revisits, %.1f s\n",
                o.dataset.c_str(), order.size(), accepted.size(), ev.true_positives, ev.precision(), ev.recall(),
                ev.revisits, run_s);
  }
  return 0;
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
  std::string input;
  bool json = false, strict = false;
  double threshold = cdc::graph::PcmOptions{}.chi2_threshold;
  CLI::App* pcm = app.add_subcommand("pcm", "run PCM over a multi-robot g2o folder (or one g2o file)");
  pcm->add_option("input", input, "folder of per-robot .g2o files, or one .g2o file")->required()->check(CLI::ExistingPath);
  pcm->add_option("--chi2", threshold, "Mahalanobis threshold on a cycle (6 DoF)")->check(CLI::PositiveNumber)
      ->capture_default_str();
  pcm->add_flag("--json", json, "print one JSON object with the accepted and rejected loops (g2o vertex ids)");
  pcm->add_flag("--strict", strict, "fail on damaged lines instead of skipping them");
  RunOptions ro_run;
  CLI::App* run = app.add_subcommand("run", "loop closure over a cdc-sim dataset folder, judged against its ground truth");
  run->add_option("dataset", ro_run.dataset, "dataset folder (cdc-sim generate)")->required()->check(CLI::ExistingDirectory);
  run->add_option("--out", ro_run.out, "write keyframes.csv, loops.csv and report.json here");
  run->add_option("--keyframe-m", ro_run.keyframe_m, "keyframe every this far [m]")->check(CLI::PositiveNumber)->capture_default_str();
  run->add_option("--noise-m", ro_run.noise_m, "odometry noise per keyframe, translation sigma [m]")->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  run->add_option("--noise-rad", ro_run.noise_rad, "odometry noise per keyframe, rotation sigma [rad]")
      ->check(CLI::NonNegativeNumber)->capture_default_str();
  run->add_option("--seed", ro_run.seed, "noise seed")->capture_default_str();
  run->add_option("--max-scans", ro_run.max_scans, "scans per robot (0: all)")->capture_default_str();
  std::string run_config;
  double run_chi2 = ro_run.params.pcm.chi2_threshold;
  size_t run_support = ro_run.params.min_inter_support;
  run->add_option("--config", run_config,
                  "the service's configuration (services/loop_closure/config/loop_closure.yaml) for the core's parameters;\n"
                  "default: their built-in defaults. --chi2 and --min-support override it")
      ->check(CLI::ExistingFile);
  CLI::Option* chi2_opt = run->add_option("--chi2", run_chi2, "PCM threshold")->check(CLI::PositiveNumber)->capture_default_str();
  CLI::Option* support_opt =
      run->add_option("--min-support", run_support, "inter-robot loops are published from a PCM-consistent set at least this large")
          ->check(CLI::PositiveNumber)->capture_default_str();
  run->add_flag("--json", ro_run.json, "print the report as one JSON object");
  CLI11_PARSE(app, argc, argv);
  if (run->parsed()) {
    try {
      if (!run_config.empty()) ro_run.params = cdc::loops::load_loop_options(run_config).core;
      if (chi2_opt->count() > 0 || run_config.empty()) ro_run.params.pcm.chi2_threshold = run_chi2;
      if (support_opt->count() > 0 || run_config.empty()) ro_run.params.min_inter_support = run_support;
      return run_dataset(ro_run);
    } catch (const std::exception& e) {
      std::cerr << "cdc-loops: " << e.what() << '\n';
      return 1;
    }
  }
  try {
    std::vector<std::string> warnings;
    cdc::graph::G2oReadOptions ro;
    ro.skip_malformed = !strict;
    ro.warnings = &warnings;
    const cdc::graph::PoseGraph g = std::filesystem::is_directory(input) ? cdc::graph::read_g2o_folder(input, ro)
                                                                          : cdc::graph::read_g2o(input, ro);
    for (const auto& w : warnings) {
      std::cerr << "cdc-loops: warning: " << w << '\n';
    }
    cdc::graph::PcmOptions po;
    po.chi2_threshold = threshold;
    const cdc::graph::OutlierDecision d = cdc::graph::Pcm(po).decide(g);
    auto ids = [&](const std::vector<size_t>& factors) {
      nlohmann::json a = nlohmann::json::array();
      for (size_t f : factors) {
        a.push_back({cdc::graph::to_g2o_key(g, g.factors[f].a), cdc::graph::to_g2o_key(g, g.factors[f].b)});
      }
      return a;
    };
    if (json) {
      nlohmann::json j{{"accepted", ids(d.accepted)}, {"rejected", ids(d.rejected)}, {"skipped_lines", warnings.size()},
                       {"chi2_threshold", threshold}};
      std::cout << j.dump() << '\n';
    } else {
      std::cout << input << ": " << d.accepted.size() << " inter-robot loop closures kept, " << d.rejected.size()
                << " rejected (chi2 " << threshold << ")\n";
    }
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "cdc-loops: " << e.what() << '\n';
    return 1;
  }
}
