#include "cdc/loop_closure/loop_core.hpp"

#include <algorithm>

namespace cdc::loops {

LoopCore::LoopCore(const LoopParams& params) : p_(params), db_(params.scan_context.rings) {}

std::vector<LoopOut> LoopCore::add_keyframe(KeyframeIn kf) {
  std::vector<LoopOut> out;
  const auto me = std::make_pair(kf.robot, kf.id);
  if (kf.id > 0) {
    odometry_.add_between(graph::make_key(kf.robot, kf.id - 1u), graph::make_key(kf.robot, kf.id), kf.T_prev,
                          kf.information);
  }
  const lidar::ScanContext sc = lidar::make_scan_context(kf.cloud, p_.scan_context);
  // Candidates among earlier keyframes, excluding this robot's recent ones.
  ++stats_.queries;
  const auto candidates = db_.query(sc, p_.knn, [&](size_t id) {
    const auto& [robot, k] = owner_[id];
    return robot != kf.robot || k + p_.exclude_recent < kf.id;
  });
  clouds_[me] = lidar::voxel_downsample(kf.cloud, p_.registration.voxel_m);
  const size_t own_id = db_.add(sc);
  owner_.push_back(me);
  (void)own_id;

  size_t verified = 0;
  std::set<uint32_t> paired_robots;
  for (const auto& c : candidates) {
    if (c.match.distance > p_.max_sc_distance || verified >= p_.max_verify) break;
    ++stats_.candidates;
    ++verified;
    const auto [robot_a, kf_a] = owner_[c.id];
    // The query is rotated by yaw relative to the candidate: T_candidate_query starts at Rz(-yaw).
    Eigen::Isometry3d guess = Eigen::Isometry3d::Identity();
    guess.linear() = Eigen::AngleAxisd(-c.match.yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    lidar::RegistrationParams rp = p_.registration;
    rp.voxel_m = 0;  // already downsampled
    const lidar::RegistrationResult r = lidar::register_clouds(clouds_[me], clouds_[{robot_a, kf_a}], guess, rp);
    ++stats_.verified;
    if (!r.converged || r.fitness > p_.max_fitness || r.overlap < p_.min_overlap) {
      ++stats_.verification_failed;
      continue;
    }
    LoopOut loop{robot_a, kf_a, kf.robot, kf.id, r.T_target_source, r.information, r.fitness, false};
    if (robot_a == kf.robot) {
      // An intra-robot loop must agree with the robot's own odometry between the two keyframes.
      graph::Factor f;
      f.kind = graph::FactorKind::kLoop;
      f.a = graph::make_key(robot_a, kf_a);
      f.b = graph::make_key(kf.robot, kf.id);
      f.measurement = loop.T_a_b;
      f.information = loop.information;
      if (graph::Pcm::odometry_distance(odometry_, f) > p_.pcm.chi2_threshold) {
        ++stats_.intra_inconsistent;
        continue;
      }
      ++stats_.intra_accepted;
      odometry_.add_between(f.a, f.b, loop.T_a_b, loop.information);
      out.push_back(loop);
      continue;
    }
    ++stats_.inter_proposed;
    odometry_.add_between(graph::make_key(robot_a, kf_a), graph::make_key(kf.robot, kf.id), loop.T_a_b, loop.information);
    const size_t f = odometry_.factors.size() - 1;
    inter_[{std::min(robot_a, kf.robot), std::max(robot_a, kf.robot)}].push_back(f);
    proposed_[f] = loop;
    paired_robots.insert(robot_a);
  }
  for (uint32_t other : paired_robots) {
    const auto changes = update_pcm(std::min(other, kf.robot), std::max(other, kf.robot));
    out.insert(out.end(), changes.begin(), changes.end());
  }
  return out;
}

std::vector<LoopOut> LoopCore::update_pcm(uint32_t a, uint32_t b) {
  std::vector<LoopOut> out;
  // PCM over this pair only: both robots' odometry and the pair's proposed loops.
  graph::PoseGraph g;
  std::vector<size_t> ids = inter_[{a, b}];
  for (const graph::Factor& f : odometry_.factors) {
    if (f.kind == graph::FactorKind::kOdometry && (graph::robot_of(f.a) == a || graph::robot_of(f.a) == b)) {
      g.factors.push_back(f);
    }
  }
  const size_t first_loop = g.factors.size();
  for (size_t f : ids) {
    g.factors.push_back(odometry_.factors[f]);
  }
  const graph::OutlierDecision d = graph::Pcm(p_.pcm).decide(g);
  std::set<size_t> accepted;
  for (size_t i : d.accepted) accepted.insert(ids[i - first_loop]);
  for (size_t f : ids) {
    const bool now = accepted.count(f) != 0, before = published_.count(f) != 0;
    if (now && !before) {
      published_.insert(f);
      ++stats_.inter_accepted;
      out.push_back(proposed_[f]);
    } else if (!now && before) {
      published_.erase(f);
      ++stats_.withdrawn;
      LoopOut w = proposed_[f];
      w.withdrawn = true;
      out.push_back(w);
    }
  }
  return out;
}

}  // namespace cdc::loops
