// cdc-bench-loops: loop-closure precision and recall on simulated three-robot KITTI runs (the
// paper's split), query time with 3,000 keyframes in the database, descriptor size.
// Keyframes every 2 m of ground truth; clouds are VLP-16 sweeps of the procedural world at the true
// pose; odometry has noise. A loop is true when its relative pose is within 1 m / 5 deg of the truth;
// a keyframe is a true revisit when an earlier keyframe (any robot, not this robot's recent ones)
// lies within 5 m. Last output line: one JSON object.
#include "cdc/dds/compact.hpp"
#include "cdc/dds/convert.hpp"
#include "cdc/io/kitti.hpp"
#include "cdc/lidar/scan_context.hpp"
#include "cdc/loop_closure/evaluation.hpp"
#include "cdc/loop_closure/loop_core.hpp"
#include "cdc/sim/lidar.hpp"
#include "cdc/sim/world.hpp"

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <random>
#include <stdexcept>

namespace {

using namespace cdc;

struct Kf {
  uint32_t robot, id;
  int64_t stamp;
  Eigen::Isometry3d truth;
};

double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size())))];
}

double median(std::vector<double> v) { return quantile(std::move(v), 0.5); }

// How a run moves clouds between robots: offline, one loop-closure core holds every robot's clouds
// (no requests); on the wire, each robot has its own core (as its service does), descriptors reach
// every robot and a verification against a peer's keyframe asks the owner's core for its cloud,
// which crosses packed as the service packs it (cdc::dds::compact, `resolution_m`).
struct WireOptions {
  bool enabled = false;
  float resolution_m = 0.02f;  // the service's default
};

struct WireCounters {
  size_t replies = 0, missing = 0, bytes = 0, points = 0;
};

nlohmann::json run_sequence(const std::string& data, const std::string& seq, const loops::LoopParams& params,
                            const io::SplitOptions& split, const WireOptions& wire, bool follow_ground) {
  const auto full = io::kitti_lidar_trajectory(data + "/kitti/poses/" + seq + ".txt",
                                               io::read_kitti_calib(data + "/kitti/calib_Tr.txt", "Tr_04_10"));
  const auto robots = io::split_robots(full, split);
  const uint32_t exclude_recent = params.exclude_recent;
  std::vector<std::vector<Eigen::Vector3d>> paths;
  std::vector<Kf> kfs;
  for (uint32_t r = 0; r < robots.size(); ++r) {
    std::vector<Eigen::Vector3d> path;
    Eigen::Vector3d last(1e9, 0, 0);
    uint32_t id = 0;
    for (const auto& sp : robots[r]) {
      path.push_back(sp.pose.translation());
      if ((sp.pose.translation() - last).norm() >= 2.0) {
        kfs.push_back({r, id++, sp.stamp_ns, sp.pose});
        last = sp.pose.translation();
      }
    }
    paths.push_back(path);
  }
  std::stable_sort(kfs.begin(), kfs.end(), [](const Kf& a, const Kf& b) { return a.stamp < b.stamp; });
  sim::WorldOptions wo;
  wo.seed = 5;
  const sim::World world = sim::World::generate(paths, wo);
  // Where the ground truth's passes over a place disagree in height, the world's ground follows the
  // lowest and a higher pass drives above it, as over a bridge; --follow-ground puts every keyframe
  // on the ground instead (its sensor at the world's sensor height above it).
  for (Kf& k : kfs) {
    if (!follow_ground) break;
    const Eigen::Vector3d t = k.truth.translation();
    k.truth.translation().z() = world.ground_height(t.x(), t.y()) + wo.sensor_height_m;
  }
  sim::LidarModel lidar = sim::LidarModel::vlp16();
  std::mt19937_64 rng(9);
  std::normal_distribution<double> nt(0, 0.02), nr(0, 0.002);
  loops::LoopCore core(params);
  std::vector<std::unique_ptr<loops::LoopCore>> robot_cores;  // the wire run's, one per robot
  for (uint32_t r = 0; wire.enabled && r < robots.size(); ++r) {
    robot_cores.push_back(std::make_unique<loops::LoopCore>(params, r));
  }
  WireCounters wc;
  std::map<std::pair<uint32_t, uint32_t>, Eigen::Isometry3d> truth;
  std::map<uint32_t, Eigen::Isometry3d> prev_truth, odom;
  // Accepted loops, one per keyframe pair whichever robot's core found it.
  std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t>, loops::LoopOut> accepted;
  auto take = [&](const loops::LoopOut& l) {
    const bool swap = std::make_pair(l.robot_a, l.keyframe_a) > std::make_pair(l.robot_b, l.keyframe_b);
    const auto key = swap ? std::make_tuple(l.robot_b, l.keyframe_b, l.robot_a, l.keyframe_a)
                          : std::make_tuple(l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b);
    if (std::getenv("CDC_BENCH_TRACE") != nullptr && l.robot_a != l.robot_b) {
      const Eigen::Isometry3d gt = truth.at({l.robot_a, l.keyframe_a}).inverse() * truth.at({l.robot_b, l.keyframe_b});
      const Eigen::Isometry3d e = gt.inverse() * l.T_a_b;
      Eigen::Matrix<double, 6, 1> r;
      r << e.translation(), Eigen::AngleAxisd(e.rotation()).angle() * Eigen::AngleAxisd(e.rotation()).axis();
      std::printf("%s %u/%u - %u/%u  error %.3f m %.2f deg  nees %.1f  fitness %.4f\n",
                  l.withdrawn ? "withdraw" : "publish", l.robot_a, l.keyframe_a, l.robot_b, l.keyframe_b,
                  e.translation().norm(), Eigen::AngleAxisd(e.rotation()).angle() * 180 / M_PI,
                  r.dot(l.information * r), l.fitness);
    }
    if (l.withdrawn)
      accepted.erase(key);
    else
      accepted[key] = l;
  };
  // The wire run: events of robot r's core; a cloud request is answered from its owner's core.
  auto settle = [&](uint32_t r, loops::LoopEvents ev, loops::Nanos now) {
    std::vector<std::pair<uint32_t, loops::LoopEvents>> todo;
    todo.emplace_back(r, std::move(ev));
    while (!todo.empty()) {
      auto [who, e] = std::move(todo.back());
      todo.pop_back();
      for (const auto& l : e.loops) take(l);
      for (const auto& q : e.requests) {
        const std::vector<Eigen::Vector3f>* held = robot_cores.at(q.robot)->cloud(q.robot, q.id);
        if (held == nullptr) {
          ++wc.missing;
          robot_cores[who]->on_cloud_missing(q.robot, q.id, now);
          continue;
        }
        const dds::compact::PackedCloud packed = dds::compact::pack_points(*held, wire.resolution_m);
        std::vector<Eigen::Vector3f> got;
        const std::string err = dds::compact::unpack_points(packed.bytes.data(), packed.bytes.size(), packed.count,
                                                            packed.resolution_m, got);
        if (!err.empty()) throw std::runtime_error("cdc-bench-loops: a packed cloud did not unpack: " + err);
        ++wc.replies;
        wc.bytes += packed.bytes.size();
        wc.points += packed.count;
        todo.emplace_back(who, robot_cores[who]->on_cloud(q.robot, q.id, std::move(got), now));
      }
    }
  };
  std::vector<lidar::ScanContext> contexts;
  const auto t0 = std::chrono::steady_clock::now();
  for (const Kf& k : kfs) {
    const auto pts = sim::sweep(
        world, lidar, [&](double) { return k.truth; }, rng);
    loops::KeyframeIn in;
    in.robot = k.robot;
    in.id = k.id;
    if (k.id > 0) {
      Eigen::Isometry3d noise = Eigen::Isometry3d::Identity();
      noise.translation() = Eigen::Vector3d(nt(rng), nt(rng), nt(rng));
      noise.linear() =
          (Eigen::AngleAxisd(nr(rng), Eigen::Vector3d::UnitZ()) * Eigen::AngleAxisd(nr(rng), Eigen::Vector3d::UnitY()))
              .toRotationMatrix();
      // As the keyframe message carries it (a rotation renormalised from its quaternion: the
      // ground truth's rotations are orthonormal only to the digits KITTI prints).
      in.T_prev = dds::to_eigen(dds::to_msg(prev_truth[k.robot].inverse() * k.truth * noise));
    }
    in.information.diagonal() << 2500, 2500, 2500, 250000, 250000, 250000;
    in.T_odom = k.truth;  // a levelled odometry's tilt: the truth's (world z is up)
    for (const auto& p : pts) in.cloud.emplace_back(p.x, p.y, p.z);
    prev_truth[k.robot] = k.truth;
    truth[{k.robot, k.id}] = k.truth;
    odom[k.robot] = k.id == 0 ? k.truth : odom[k.robot] * in.T_prev;
    contexts.push_back(lidar::make_scan_context(in.cloud, params.scan_context));
    if (!wire.enabled) {
      for (const auto& l : core.add_keyframe(std::move(in))) take(l);
      continue;
    }
    const loops::Nanos now(k.stamp);
    loops::DescriptorIn d;
    d.robot = k.robot;
    d.id = k.id;
    d.context = loops::wire_form(contexts.back());
    d.pose_hint = dds::to_eigen(dds::to_msg_f(odom[k.robot]));  // as the descriptor message carries it
    settle(k.robot, robot_cores[k.robot]->add_keyframe_data(std::move(in), now), now);
    for (uint32_t r = 0; r < robot_cores.size(); ++r) {
      settle(r, robot_cores[r]->add_descriptor(d, now), now);
      settle(r, robot_cores[r]->tick(now), now);
    }
  }
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::vector<loops::TruthKeyframe> order;
  for (const Kf& k : kfs) order.push_back({k.robot, k.id, k.truth});
  std::vector<loops::LoopOut> standing;
  for (const auto& [key, l] : accepted) standing.push_back(l);
  loops::EvaluationOptions eo;
  eo.exclude_recent = exclude_recent;
  const loops::LoopEvaluation ev = loops::evaluate_loops(order, standing, eo);
  if (std::getenv("CDC_BENCH_VERBOSE") != nullptr) {
    for (const auto& v : ev.loops) {
      if (!v.correct) {
        std::printf("false loop %u/%u - %u/%u: error %.2f m %.1f deg, fitness %.3f\n", v.loop.robot_a,
                    v.loop.keyframe_a, v.loop.robot_b, v.loop.keyframe_b, v.error_m, v.error_deg, v.loop.fitness);
      }
    }
    for (const auto& [robot, id] : ev.missed) std::printf("missed revisit %u/%u\n", robot, id);
  }
  const size_t tp = ev.true_positives, false_intra = ev.false_intra, false_inter = ev.false_inter;
  const size_t revisits = ev.revisits;
  // Quantisation: the accept decision of every candidate is the same on quantised descriptors.
  size_t decisions = 0, changed = 0;
  double max_change = 0;
  for (size_t i = 0; i + 1 < contexts.size(); i += 7) {
    const lidar::ScanContext qi = loops::wire_form(contexts[i]);
    for (size_t j = i + 1; j < contexts.size(); j += 13) {
      const lidar::ScanContext qj = loops::wire_form(contexts[j]);
      const double da = lidar::compare(contexts[j], contexts[i]).distance, db = lidar::compare(qj, qi).distance;
      max_change = std::max(max_change, std::abs(da - db));
      const bool a = da <= params.max_sc_distance;
      const bool b = db <= params.max_sc_distance;
      ++decisions;
      changed += a != b ? 1 : 0;
    }
  }
  // How well the true inter-robot loops register (a coarser cloud on the wire shows here first).
  std::vector<double> inter_m, inter_deg;
  for (const auto& v : ev.loops) {
    if (v.correct && v.loop.robot_a != v.loop.robot_b) {
      inter_m.push_back(v.error_m);
      inter_deg.push_back(v.error_deg);
    }
  }
  auto stat = [&](uint64_t loops::LoopStats::*field) {
    uint64_t n = core.stats().*field;
    for (const auto& c : robot_cores) n += c->stats().*field;
    return n;
  };
  nlohmann::json j{
      {"keyframes", kfs.size()},
      {"accepted", accepted.size()},
      {"true_positives", tp},
      {"false_intra", false_intra},
      {"false_inter", false_inter},
      {"precision", accepted.empty() ? 1.0 : static_cast<double>(tp) / static_cast<double>(accepted.size())},
      {"revisits", revisits},
      {"recall", ev.recall()},
      {"verified", stat(&loops::LoopStats::verified)},
      {"verification_failed", stat(&loops::LoopStats::verification_failed)},
      {"inter_accepted", stat(&loops::LoopStats::inter_accepted)},
      {"intra_accepted", stat(&loops::LoopStats::intra_accepted)},
      {"intra_inconsistent", stat(&loops::LoopStats::intra_inconsistent)},
      {"inter_proposed", stat(&loops::LoopStats::inter_proposed)},
      {"withdrawn", stat(&loops::LoopStats::withdrawn)},
      {"failed_not_converged", stat(&loops::LoopStats::failed_not_converged)},
      {"failed_fitness", stat(&loops::LoopStats::failed_fitness)},
      {"failed_overlap", stat(&loops::LoopStats::failed_overlap)},
      {"skipped_near_requested", stat(&loops::LoopStats::skipped_near_requested)},
      {"verified_with_neighbour", stat(&loops::LoopStats::verified_with_neighbour)},
      {"reaim_too_far", stat(&loops::LoopStats::reaim_too_far)},
      {"reverse_queries", stat(&loops::LoopStats::reverse_queries)},
      {"left_to_lower_robot", stat(&loops::LoopStats::left_to_lower_robot)},
      {"quantization_decisions", decisions},
      {"quantization_changed", changed},
      {"quantization_max_distance_change", max_change},
      {"inter_true", inter_m.size()},
      {"inter_error_m_median", median(inter_m)},
      {"inter_error_m_p90", quantile(inter_m, 0.9)},
      {"inter_error_deg_median", median(inter_deg)},
      {"inter_error_deg_p90", quantile(inter_deg, 0.9)},
      {"run_s", run_s}};
  std::printf(
      "KITTI %s: %zu keyframes, %zu loops accepted (%zu true), precision %.3f, recall %.3f of %zu revisits, %.1f s\n",
      seq.c_str(), kfs.size(), accepted.size(), tp, j["precision"].get<double>(), j["recall"].get<double>(), revisits,
      run_s);
  std::printf("  %zu true inter-robot loops: error median %.3f m / %.3f deg, 90th percentile %.3f m / %.3f deg\n",
              inter_m.size(), median(inter_m), median(inter_deg), quantile(inter_m, 0.9), quantile(inter_deg, 0.9));
  if (wire.enabled) {
    j["wire"] = {
        {"resolution_m", wire.resolution_m},
        {"cloud_replies", wc.replies},
        {"cloud_missing", wc.missing},
        {"cloud_bytes", wc.bytes},
        {"bytes_per_reply", wc.replies == 0 ? 0.0 : static_cast<double>(wc.bytes) / static_cast<double>(wc.replies)},
        {"points_per_reply", wc.replies == 0 ? 0.0 : static_cast<double>(wc.points) / static_cast<double>(wc.replies)},
        {"cloud_bytes_per_keyframe", static_cast<double>(wc.bytes) / static_cast<double>(kfs.size())}};
    // How the registrations spread over the robots (the lower robot of a pair verifies it).
    nlohmann::json per_robot = nlohmann::json::array();
    for (const auto& c : robot_cores) per_robot.push_back(c->stats().verified);
    j["wire"]["verified_per_robot"] = per_robot;
    std::printf("  on the wire (%.3f m): %zu cloud replies, %.0f B each (%.0f points), %.0f B per keyframe\n",
                wire.resolution_m, wc.replies, j["wire"]["bytes_per_reply"].get<double>(),
                j["wire"]["points_per_reply"].get<double>(), j["wire"]["cloud_bytes_per_keyframe"].get<double>());
  }
  return j;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"cdc-bench-loops: loop-closure precision/recall on simulated three-robot KITTI runs"};
  const char* env = std::getenv("CDC_DATA_DIR");
  std::string data = env != nullptr ? env : "../shared/data";
  std::vector<std::string> seqs = {"05", "09"};
  app.add_option("--data", data, "reference data folder (CDC_DATA_DIR)")->capture_default_str();
  app.add_option("--seq", seqs, "KITTI sequences")->capture_default_str();
  loops::LoopParams defaults;
  double chi2 = defaults.pcm.chi2_threshold;
  app.add_option("--pcm-chi2", chi2, "PCM threshold")->capture_default_str();
  app.add_option("--min-overlap", defaults.min_overlap, "verification: least overlap")->capture_default_str();
  app.add_option("--max-fitness", defaults.max_fitness, "verification: largest fitness [m^2]")->capture_default_str();
  app.add_option("--max-sc-distance", defaults.max_sc_distance, "retrieval: Scan Context distance")
      ->capture_default_str();
  app.add_option("--max-verify", defaults.max_verify, "candidates verified per keyframe")->capture_default_str();
  app.add_option("--ground-guess-min", defaults.ground_guess_min_m,
                 "verification: level the guess with both grounds beyond this height difference [m]")
      ->capture_default_str();
  app.add_option(
         "--reaim-max", defaults.reaim_max_m,
         "with --wire: largest offset [m] at which a candidate is verified against a neighbour's cloud (0: any)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option(
         "--peer-request-spacing", defaults.peer_request_spacing,
         "with --wire: no cloud request within this many keyframes of a peer keyframe already requested (0: none)")
      ->capture_default_str();
  WireOptions wire;
  app.add_flag("--wire", wire.enabled,
               "one loop-closure core per robot, peers' clouds requested and packed as the service sends them");
  app.add_option(
         "--reply-resolution", wire.resolution_m,
         "with --wire: quantisation of the packed clouds [m] (loop_closure.yaml's verification.reply_resolution_m)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  io::SplitOptions split;
  app.add_option("--reverse", split.reverse,
                 "robots that drive their piece the other way, on the opposite lane (io::SplitOptions::reverse)");
  app.add_option("--reverse-lane", split.reverse_lane_m, "how far left of the sequence's direction they drive [m]")
      ->capture_default_str();
  bool follow_ground = false;
  app.add_flag("--follow-ground", follow_ground,
               "keyframes on the simulated ground (where the ground truth's passes disagree in height)");
  bool both_verify = false;
  app.add_flag("--both-robots-verify", both_verify,
               "with --wire: both robots of a pair verify it (lower_robot_verifies: false)");
  CLI11_PARSE(app, argc, argv);
  defaults.lower_robot_verifies = !both_verify;
  if (!std::filesystem::exists(data + "/kitti/poses")) {
    std::cerr << "cdc-bench-loops: " << data << "/kitti/poses not found (set --data or CDC_DATA_DIR)\n";
    return 2;
  }
  loops::LoopParams params = defaults;
  params.pcm.chi2_threshold = chi2;
  nlohmann::json out;
  double precision = 1, recall = 1;
  for (const auto& s : seqs) {
    out[s] = run_sequence(data, s, params, split, wire, follow_ground);
    precision = std::min(precision, out[s]["precision"].get<double>());
    recall = std::min(recall, out[s]["recall"].get<double>());
  }
  // Query time with 3,000 keyframes: random places of the procedural kind, then timed queries.
  lidar::ScanContextDatabase db(params.scan_context.rings);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(0, 1);
  auto random_sc = [&] {
    lidar::ScanContext sc;
    sc.rings = params.scan_context.rings;
    sc.sectors = params.scan_context.sectors;
    sc.cells.resize(static_cast<size_t>(sc.rings * sc.sectors));
    for (auto& c : sc.cells) c = u(rng) < 0.4f ? 20 * u(rng) : 0.0f;
    lidar::compute_ring_key(sc);
    return sc;
  };
  for (int i = 0; i < 3000; ++i) db.add(random_sc());
  std::vector<double> ms;
  for (int i = 0; i < 200; ++i) {
    const auto q = random_sc();
    const auto t0 = std::chrono::steady_clock::now();
    const auto c = db.query(q, params.knn, [](size_t) { return true; });
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
    if (c.empty()) return 1;
  }
  lidar::ScanContext example = random_sc();
  out["precision"] = precision;
  out["recall"] = recall;
  out["query_ms"] = median(ms);
  out["query_db_size"] = db.size();
  out["descriptor_bytes"] = lidar::quantize(example).bytes();
  std::printf("query: median %.3f ms with %zu keyframes; descriptor %zu bytes on the wire\n", median(ms), db.size(),
              out["descriptor_bytes"].get<size_t>());
  std::cout << out.dump() << '\n';
  return 0;
}
