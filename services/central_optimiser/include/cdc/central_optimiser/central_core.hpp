// The central optimiser's synchronous core: one global pose graph for every robot (paper
// eq. 3-6: a prior on robot 0's first keyframe only, odometry, intra- and inter-robot loops).
// No DDS, no threads: the node feeds it validated inputs and publishes what it returns.
#pragma once

#include "cdc/graph/pose_graph.hpp"
#include "cdc/graph/solver.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace cdc::central {

// Accepted loops a full pass needs before their residuals set GNC's threshold.
inline constexpr size_t kGncCalibrationLoops = 20;
// A held-out loop within kGncRetryFactor c^2 of a converged full pass takes part in GNC again, at
// most kGncMaxRetries times.
inline constexpr double kGncRetryFactor = 4.0;
inline constexpr uint8_t kGncMaxRetries = 2;

using graph::Key;
using graph::Matrix6d;

struct KeyframeIn {
  uint32_t robot = 0;
  uint32_t incarnation = 0;
  uint32_t id = 0;
  int64_t stamp_ns = 0;
  Eigen::Isometry3d T_odom_keyframe = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d T_prev_keyframe = Eigen::Isometry3d::Identity();  // from id - 1
  Matrix6d information = Matrix6d::Identity();
};

struct LoopIn {
  uint32_t sender = 0;
  uint32_t sender_incarnation = 0;
  uint32_t seq = 0;
  uint32_t robot_a = 0, keyframe_a = 0, robot_b = 0, keyframe_b = 0;
  bool withdrawn = false;
  Eigen::Isometry3d T_a_b = Eigen::Isometry3d::Identity();
  Matrix6d information = Matrix6d::Identity();
};

enum class Outcome { kAccepted, kDuplicate, kRejected };

struct AddResult {
  Outcome outcome = Outcome::kAccepted;
  std::string reason;  // for rejections
};

struct CentralConfig {
  uint32_t robot_count = 3;
  int max_iterations_per_update = 10;
  double max_time_per_update_s = 0.05;
  // Cauchy scale on loop factors in whitened units (0: none). 3 is about the 95 % chi-square
  // radius of a 6-DoF residual: inlier loops stay quadratic, gross outliers are discounted.
  double loop_robust_scale = 3.0;
  // Graduated non-convexity on loop closures in full passes (graph::GncOptions: truncated least
  // squares from the least-squares solution). A full pass takes GNC rounds only when some loop's
  // squared residual r^T Omega r exceeds the threshold c^2 at the least-squares solution, so a
  // graph without wrong loops costs what it did. A loop that a converged full pass rejects stays out
  // of later passes until a converged full pass finds it within c^2 of the graph without it. Local
  // passes keep the Cauchy loss on the loops not rejected.
  bool loop_gnc = true;
  // c^2 at most; below it, c^2 follows the loops: loop_gnc_median_ratio times the median squared
  // residual of the accepted loops at the last converged full pass (with at least
  // kGncCalibrationLoops of them), since the information of registered loops is often far more
  // pessimistic than their errors and a wrong loop would then fit under the chi-square bound.
  double loop_gnc_threshold = 16.81;
  double loop_gnc_median_ratio = 100.0;
  int loop_gnc_rounds = 30;  // GNC rounds per full pass at most (mu doubles each round)
  // Loops through one keyframe share its cloud's errors: each loop's information is divided by the
  // most loops either of its keyframes takes part in (graph::share_loop_information).
  bool share_loop_information = true;
  // Loops held waiting for their keyframes (loops in the graph do not count).
  size_t max_pending_loops = 100'000;
  // Keyframes held beyond a gap in their robot session's ids (waiting for a predecessor), over all
  // sessions. One beyond the cap is refused: it is not acknowledged, so a real one is sent again.
  size_t max_pending_keyframes = 10'000;
  // Incremental updates re-optimise what changed (new keyframes, loop ends) plus this many
  // preceding keyframes of the same robot, the rest held fixed; a local update that does not
  // converge is continued by the next. The whole graph is re-optimised when a robot joins the world,
  // after a full pass that did not converge, once a robot has gained more than
  // max(window, full_growth x its keyframes) since the last full pass, and every full_every updates
  // once the graph has changed (keyframes and loops inserted) by full_growth of its size. A full
  // pass costs O(graph) and comes after O(graph) changes: the work per keyframe stays bounded as the
  // mission grows.
  uint32_t window = 30;
  uint32_t full_every = 20;
  double full_growth = 0.1;
  int full_pass_iterations = 3;
  // A bound for a slow machine, not the pass's budget: the iterations bind, so that how far a full
  // pass gets does not depend on the machine's load (wall-time bounds cut passes short under load,
  // each cut pass was followed by another, and the work per keyframe grew with the graph).
  double full_pass_time_s = 2.0;
};

struct RobotEstimate {
  uint32_t robot = 0;
  uint32_t incarnation = 0;
  Eigen::Isometry3d T_world_robot = Eigen::Isometry3d::Identity();
  std::vector<std::pair<uint32_t, Eigen::Isometry3d>> poses;  // keyframe id -> T_world_keyframe
  bool from_hint = false;  // not in the graph yet: placed by the robot's own hint (no shape of the graph's)
};

struct Acknowledgement {
  uint32_t robot = 0;
  uint32_t incarnation = 0;
  int64_t highest_contiguous_keyframe = -1;
  int64_t highest_contiguous_loop_seq = -1;  // loops sent by this robot incarnation
};

struct UpdateStats {
  bool solved = false;
  bool full = false;      // whole graph, or the changed part only
  bool converged = true;  // the solver converged within the budget (or had nothing to solve)
  int iterations = 0;
  double time_s = 0;
  double cost = 0;  // full-information cost after the update
  size_t poses = 0;
  size_t factors = 0;
};

struct Counters {
  uint64_t keyframes_accepted = 0, keyframes_duplicate = 0, keyframes_rejected = 0;
  uint64_t keyframes_pending_full = 0;  // of keyframes_rejected: refused at max_pending_keyframes
  uint64_t loops_accepted = 0, loops_duplicate = 0, loops_rejected = 0, loops_withdrawn = 0;
  uint64_t loops_outliers = 0;  // loops in the graph that GNC holds out of the solves now
};

class CentralCore {
 public:
  explicit CentralCore(const CentralConfig& config);

  AddResult add_keyframe(const KeyframeIn& kf);
  AddResult add_loop(const LoopIn& loop);
  // A robot's own estimate of T_world_robot (from its distributed back-end, on rejoin): used as the
  // initial placement of its keyframes until loops place it.
  void add_world_hint(uint32_t robot, uint32_t incarnation, const Eigen::Isometry3d& T_world_robot);

  // Incremental update, warm-started, within the configured budget: the changed part of the
  // graph, or all of it every full_every updates, and at every update while the graph is not
  // settled.
  UpdateStats optimise();
  // Called after every solver iteration (the node asserts its liveliness from it).
  void on_iteration(std::function<void()> f) { on_iteration_ = std::move(f); }
  // Solves to convergence (no budget), for final results.
  UpdateStats optimise_fully();

  // Robots placed in the world, with their current incarnation's keyframes.
  std::vector<RobotEstimate> estimates() const;
  // One robot's estimate; nullopt while it is not in the world.
  std::optional<RobotEstimate> estimate(uint32_t robot) const;
  std::vector<Acknowledgement> acknowledgements() const;
  // The anchored graph (for writing g2o and comparing optima).
  const graph::PoseGraph& graph() const noexcept { return graph_; }
  uint64_t version() const noexcept { return version_; }
  const Counters& counters() const noexcept { return counters_; }
  // Keyframes held per robot incarnation (in the graph or waiting for a predecessor).
  size_t keyframes_held(uint32_t robot, uint32_t incarnation) const;
  // Keyframes held beyond a gap in their session's ids, over all sessions (at most max_pending_keyframes).
  size_t keyframes_pending() const noexcept { return pending_keyframes_; }
  // The position in W of the robot's newest keyframe of its current session: in the graph once it is
  // placed, else from its own hint; nullopt while it is not in the world.
  std::optional<Eigen::Vector3d> newest_position(uint32_t robot) const;
  bool dirty() const noexcept { return dirty_; }
  // The loops in the graph that GNC holds out of the solves.
  std::vector<LoopIn> outlier_loops() const;
  // GNC's threshold c^2 for the next full pass (CentralConfig::loop_gnc_threshold).
  double gnc_threshold() const noexcept { return gnc_threshold_; }
  // Whether the last update converged within its budget. A large change (a robot rejoining with
  // its backlog and the loops it missed) takes several bounded passes; the estimates between them
  // are partial solutions, which a robot's front-end must not follow (the node holds them back).
  bool settled() const noexcept { return settled_; }

 private:
  // A held keyframe. Its link to the predecessor (odometry and its information) is kept only until
  // it is in the graph, where the odometry factor carries it: a long mission holds what it needs.
  struct Held {
    struct Link {
      Eigen::Isometry3d T_prev_keyframe;
      Matrix6d information;
    };
    Held(int64_t stamp, const Eigen::Isometry3d& T_odom, std::unique_ptr<Link> l)
        : stamp_ns(stamp), T_odom_keyframe(T_odom), link(std::move(l)) {}
    Held(const Held& o) : Held(o.stamp_ns, o.T_odom_keyframe, o.link ? std::make_unique<Link>(*o.link) : nullptr) {}
    Held(Held&&) noexcept = default;
    Held& operator=(Held o) noexcept {
      std::swap(stamp_ns, o.stamp_ns);
      std::swap(T_odom_keyframe, o.T_odom_keyframe);
      std::swap(link, o.link);
      return *this;
    }
    ~Held() = default;
    int64_t stamp_ns = 0;
    Eigen::Isometry3d T_odom_keyframe = Eigen::Isometry3d::Identity();
    std::unique_ptr<Link> link;
  };
  struct Session {
    uint32_t robot = 0;
    uint32_t incarnation = 0;
    uint32_t index = 0;                  // session number of this robot: key = (robot, index << 32 | id)
    std::map<uint32_t, Held> keyframes;  // held, by id: the next contiguous one is a lookup
    uint64_t contiguous = 0;             // ids 0 .. contiguous - 1 are all held
    uint32_t in_graph = 0;               // ids 0 .. in_graph - 1 are in the graph (chained from 0)
    bool has(uint32_t id) const { return id < in_graph; }
    bool placed = false;
    std::optional<Eigen::Isometry3d> hint;                           // T_world_robot from the robot
    Eigen::Isometry3d T_world_odom = Eigen::Isometry3d::Identity();  // once placed
    std::set<uint32_t> loop_seqs;                                    // loops sent by this session
    int64_t loop_contiguous = -1;                                    // seqs 0 .. loop_contiguous are all held
    uint32_t inserted_since_full = 0;  // keyframes put in the graph since the last full pass
  };
  struct StoredLoop {
    LoopIn in;
    bool in_graph = false;
    size_t factor_index = 0;
  };

  Session* session(uint32_t robot, uint32_t incarnation, bool create);
  Session* current_session(uint32_t robot);
  Key key(const Session& s, uint32_t id) const { return graph::make_key(s.robot, (uint64_t{s.index} << 32) | id); }
  void hold(Session& s, const KeyframeIn& kf);
  AddResult held_already(const Held& held, const KeyframeIn& kf);
  void insert_ready_keyframes(Session& s);
  void try_insert_loops();
  void place(Session& s, const Eigen::Isometry3d& T_world_odom);
  graph::PoseGraph take_pass_graph(std::vector<size_t>& ids);
  UpdateStats solve_with(const graph::SolverOptions& options);
  UpdateStats solve_local(const graph::SolverOptions& options);
  void touch(const Session& s, uint32_t id) { touched_.insert(key(s, id)); }
  void add_between(Key a, Key b, const Eigen::Isometry3d& T_a_b, const Matrix6d& information);
  void index_factors();
  void withdraw(StoredLoop& l);
  void hold_loop_seq(uint32_t sender, uint32_t incarnation, uint32_t seq);
  std::set<Key> active_keys() const;
  std::vector<size_t> local_factors(const std::set<Key>& active) const;
  bool full_pass_due() const;
  graph::SolverOptions update_options() const;
  graph::SolverOptions full_pass_options(graph::SolverOptions o) const;
  void review_loops(const graph::PoseGraph& pass, const std::vector<size_t>& ids, const graph::SolveResult& r);
  bool outlier(size_t factor) const { return factor < outliers_.size() && outliers_[factor] != 0; }

  CentralConfig config_;
  std::map<uint32_t, std::vector<Session>> sessions_;  // per robot, by arrival of incarnations
  std::vector<StoredLoop> loops_;
  std::vector<size_t> pending_loops_;                            // loops_ not in the graph and not withdrawn
  size_t pending_keyframes_ = 0;                                 // held beyond a gap, over all sessions
  std::set<std::tuple<uint32_t, uint32_t, uint32_t>> loop_ids_;  // (sender, incarnation, seq)
  graph::PoseGraph graph_;
  std::map<Key, std::vector<size_t>> factors_at_;  // key -> indices of graph_.factors through it
  std::map<Key, int> loop_counts_;                 // key -> loop factors through it (graph::loop_counts)
  std::vector<uint8_t> outliers_;                  // per factor of graph_: a loop GNC rejected (short: none)
  std::vector<uint8_t> retries_;                   // per factor of graph_: times it rejoined beyond c^2
  double gnc_threshold_ = 0;                       // c^2 of the next full pass
  size_t rejoined_ = 0;                            // outliers the last full pass let rejoin
  uint64_t changes_since_full_ = 0;                // keyframes and loops inserted since the last full pass
  bool last_full_ = false;                         // the last update was a full pass
  std::function<void()> on_iteration_;
  uint64_t version_ = 0;
  bool dirty_ = false;
  std::set<Key> touched_;  // keys changed since the last update
  uint32_t updates_since_full_ = 0;
  bool need_full_ = false;  // a robot joined the world, or one grew beyond the window
  bool settled_ = true;     // the last update converged
  Counters counters_;
};

}  // namespace cdc::central
