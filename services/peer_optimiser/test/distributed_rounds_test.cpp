// The peer cores of a group solving at once without a central, exchanging separators through the
// core's own API (StepOutput::separators -> PeerCore::on_separator), as the nodes do: within 30
// rounds every keyframe is within 0.05 m of the centralized solve of the same graph. The rounds
// start with robot 0 in its odometry frame and the others in theirs, placed through their peers.
#include "cdc/geometry/se3.hpp"
#include "cdc/graph/distributed.hpp"
#include "cdc/graph/g2o.hpp"
#include "cdc/graph/initialise.hpp"
#include "cdc/graph/solver.hpp"
#include "cdc/peer_optimiser/peer_core.hpp"
#include "peer_test_support.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <random>
#include <set>
#include <vector>

namespace cdc::peer {
namespace {

// What the peers of a group are given: each robot's keyframes (ids 0, 1, ... with their odometry)
// and every loop, intra- and inter-robot.
struct Group {
  std::vector<std::vector<OwnKeyframe>> keyframes;  // [robot][id]
  std::vector<LoopRecord> loops;
};

// The same graph solved jointly, robot 0's first keyframe held at its odometry pose.
graph::PoseGraph centralized(const Group& g) {
  graph::PoseGraph central;
  for (uint32_t r = 0; r < g.keyframes.size(); ++r) {
    for (const OwnKeyframe& kf : g.keyframes[r]) {
      if (kf.id > 0) {
        central.add_between(graph::make_key(r, kf.id - 1u), graph::make_key(r, kf.id), kf.T_prev, kf.information);
      }
    }
  }
  for (const LoopRecord& l : g.loops) {
    central.add_between(graph::make_key(l.robot_a, l.keyframe_a), graph::make_key(l.robot_b, l.keyframe_b), l.T_a_b,
                        l.information);
  }
  central.add_prior(graph::make_key(0, 0), g.keyframes[0][0].T_odom, Matrix6d::Identity() * 1e6);
  EXPECT_TRUE(graph::chordal_initialise(central));
  graph::SolverOptions o;
  o.robust_loss_scale = 0.0;  // as the rounds solve
  o.function_tolerance = 1e-12;
  o.max_iterations = 200;
  graph::solve(central, o);
  return central;
}

struct Rounds {
  std::vector<double> worst_m;                // after each round: the largest keyframe deviation [m]
  std::map<uint32_t, uint64_t> poses, loops;  // separator poses and relayed loops sent, per robot
  int rounds_to(double tolerance_m) const {   // the first round within the tolerance (0: none)
    for (size_t i = 0; i < worst_m.size(); ++i) {
      if (worst_m[i] <= tolerance_m) return static_cast<int>(i + 1);
    }
    return 0;
  }
};

// One PeerCore per robot with every record it would receive (its keyframes, the loops touching
// it), all stepping at once every 100 ms; separators delivered after each step.
Rounds run_group(const Group& g, PeerConfig base, int rounds) {
  const graph::PoseGraph central = centralized(g);
  const auto robots = static_cast<uint32_t>(g.keyframes.size());
  std::vector<PeerCore> cores;
  for (uint32_t r = 0; r < robots; ++r) {
    base.robot = r;
    base.robot_count = robots;
    cores.emplace_back(base);
    for (const OwnKeyframe& kf : g.keyframes[r]) cores.back().add_keyframe(kf, 0s);
  }
  for (const LoopRecord& l : g.loops) add_loop_to_its_robots(cores, l);
  Rounds out;
  Nanos t = 0s;
  for (int i = 0; i < rounds; ++i) {
    t += 100ms;
    const std::vector<StepOutput> steps = exchange_round(cores, t);
    for (uint32_t r = 0; r < robots; ++r) {
      for (const SeparatorOut& s : steps[r].separators) {
        out.poses[r] += s.poses.size();
        out.loops[r] += s.loops.size();
      }
    }
    double worst = 0;
    for (uint32_t r = 0; r < robots; ++r) {
      for (const auto& [k, T] : cores[r].graph().poses) {
        if (graph::robot_of(k) == r) {
          worst = std::max(worst, (T.translation() - central.poses.at(k).translation()).norm());
        }
      }
    }
    out.worst_m.push_back(worst);
  }
  return out;
}

PeerConfig group_config() {
  PeerConfig c = config(0);
  c.separator_min_change_m = 1e-4;
  c.separator_min_change_rad = 1e-5;
  c.share_loop_information = false;  // the centralized solve weighs every loop as measured
  return c;
}

// Separator poses travel as cdc_msg_KeyframePoseF (graph::kSeparatorPoseBytes each); a relayed loop
// is sent once to each robot that needs it.
void report(const char* name, const Rounds& r, uint32_t robots) {
  const double n = static_cast<double>(r.worst_m.size());
  std::printf("%s: worst deviation after 10 / 20 / 30 rounds %.3f / %.3f / %.3f m, within 0.05 m from round %d\n", name,
              r.worst_m[9], r.worst_m[19], r.worst_m[29], r.rounds_to(0.05));
  for (uint32_t robot = 0; robot < robots; ++robot) {
    const double pose_bytes = static_cast<double>(r.poses.at(robot) * graph::kSeparatorPoseBytes);
    std::printf("  robot %u: %.0f bytes of separator poses per round, %llu loops relayed\n", robot, pose_bytes / n,
                static_cast<unsigned long long>(r.loops.at(robot)));
  }
}

// A robot's keyframe order from a g2o graph: a path through its poses along its intra-robot edges
// (found by depth-first search from its smallest key), so that consecutive keyframes share an edge.
std::vector<graph::Key> odometry_path(const graph::PoseGraph& g, uint32_t robot) {
  std::map<graph::Key, std::set<graph::Key>> next;
  std::set<graph::Key> keys;
  for (const auto& [k, T] : g.poses) {
    if (graph::robot_of(k) == robot) keys.insert(k);
  }
  for (const graph::Factor& f : g.factors) {
    if (graph::robot_of(f.a) == robot && graph::robot_of(f.b) == robot) {
      next[f.a].insert(f.b);
      next[f.b].insert(f.a);
    }
  }
  std::vector<graph::Key> path{*keys.begin()};
  std::set<graph::Key> on_path{path.front()};
  std::function<bool()> extend = [&]() {
    if (path.size() == keys.size()) return true;
    for (graph::Key k : next[path.back()]) {
      if (!on_path.insert(k).second) continue;
      path.push_back(k);
      if (extend()) return true;
      path.pop_back();
      on_path.erase(k);
    }
    return false;
  };
  EXPECT_TRUE(extend()) << "no path through robot " << robot << "'s poses along its edges";
  return path;
}

// A multi-robot graph (a g2o folder's) as the peers would receive it: each robot's path of poses as its
// keyframes (odometry: the edges along the path, chained from the identity), every other edge as a
// loop.
Group group_from_graph(const graph::PoseGraph& g, uint32_t robots) {
  Group out;
  std::map<graph::Key, std::pair<uint32_t, uint32_t>> where;  // key -> robot, keyframe id
  std::map<std::pair<graph::Key, graph::Key>, const graph::Factor*> edges;
  for (const graph::Factor& f : g.factors) edges[{f.a, f.b}] = &f;
  std::set<const graph::Factor*> odometry;
  for (uint32_t r = 0; r < robots; ++r) {
    const std::vector<graph::Key> path = odometry_path(g, r);
    out.keyframes.emplace_back();
    for (uint32_t id = 0; id < path.size(); ++id) {
      where[path[id]] = {r, id};
      OwnKeyframe kf;
      kf.id = id;
      if (id > 0) {
        const auto fwd = edges.find({path[id - 1], path[id]});
        const graph::Factor* f = fwd != edges.end() ? fwd->second : edges.at({path[id], path[id - 1]});
        odometry.insert(f);
        kf.T_prev = fwd != edges.end() ? f->measurement : f->measurement.inverse();
        kf.information = f->information;  // the edges of these sets have isotropic information
        kf.T_odom = out.keyframes[r].back().T_odom * kf.T_prev;
      }
      out.keyframes[r].push_back(kf);
    }
  }
  uint32_t seq = 0;
  for (const graph::Factor& f : g.factors) {
    if (odometry.count(&f) != 0) continue;
    const auto [ra, ia] = where.at(f.a);
    const auto [rb, ib] = where.at(f.b);
    out.loops.push_back(LoopRecord{ra, 3, seq++, ra, ia, rb, ib, false, f.measurement, f.information});
  }
  return out;
}

std::string dgs_folder(const std::string& name) {
  const char* env = std::getenv("CDC_DATA_DIR");
  return (std::filesystem::path(env != nullptr ? env : "../shared/data") / "multi-robot/dgs" / name).string();
}

TEST(DistributedRounds, FourPeersReachTheCentralizedSolveInShapeWithin30Rounds) {
  const std::string folder = dgs_folder("example_4robots");
  if (!std::filesystem::exists(folder)) {
    GTEST_SKIP() << "reference data absent: " << folder << " not found";
  }
  const Group g = group_from_graph(graph::read_g2o_folder(folder), 4);
  const Rounds r = run_group(g, group_config(), 30);
  report("example_4robots, coarse step", r, 4);
  EXPECT_LE(r.worst_m.back(), 0.05);
  EXPECT_GT(r.loops.at(0), 0u) << "robot 0 relayed none of its loops with robots 1 and 2";
}

// A generated group of the same family: a grid of poses 16 x 3 x 2 (2 m apart) cut into four robots
// along x, an edge between every two neighbours with seeded noise (0.05 m, 0.01 rad). Chained
// through their paths, the noise bends each robot's odometry; the centralized solve straightens it.
graph::PoseGraph grid_group(uint32_t robots) {
  constexpr uint32_t kLength = 4, kWidth = 3, kHeight = 2;  // poses per robot along x, y, z
  constexpr double kSpacing = 2.0, kSigmaT = 0.05, kSigmaR = 0.01;
  std::mt19937 rng(7);
  std::normal_distribution<double> unit(0.0, 1.0);
  const auto key = [&](uint32_t x, uint32_t y, uint32_t z) {
    return graph::make_key(x / kLength, ((x % kLength) * kWidth + y) * kHeight + z);
  };
  graph::PoseGraph g;
  for (uint32_t x = 0; x < kLength * robots; ++x) {
    for (uint32_t y = 0; y < kWidth; ++y) {
      for (uint32_t z = 0; z < kHeight; ++z) {
        g.poses[key(x, y, z)] = Eigen::Isometry3d(Eigen::Translation3d(kSpacing * Eigen::Vector3d(x, y, z)));
      }
    }
  }
  Matrix6d information = Matrix6d::Identity() / (kSigmaT * kSigmaT);
  information.bottomRightCorner<3, 3>() = Eigen::Matrix3d::Identity() / (kSigmaR * kSigmaR);
  for (const auto& [a, T_a] : g.poses) {
    for (const auto& [b, T_b] : g.poses) {
      if (a < b && std::abs((T_b.translation() - T_a.translation()).norm() - kSpacing) < 1e-9) {
        geometry::Vector6d noise;
        for (int i = 0; i < 6; ++i) noise[i] = unit(rng) * (i < 3 ? kSigmaT : kSigmaR);
        g.add_between(a, b, T_a.inverse() * T_b * geometry::se3_exp(noise), information);
      }
    }
  }
  return g;
}

TEST(DistributedRounds, FourPeersRemoveTheBendOfAGeneratedGridWithin30Rounds) {
  const Group g = group_from_graph(grid_group(4), 4);
  const Rounds r = run_group(g, group_config(), 30);
  report("generated 4-robot grid, coarse step", r, 4);
  EXPECT_LE(r.worst_m.back(), 0.05);
}

}  // namespace
}  // namespace cdc::peer
