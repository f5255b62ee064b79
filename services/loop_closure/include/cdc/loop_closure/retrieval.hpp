// Retrieval: every robot's keyframe descriptors in one Scan Context database, and the search that
// turns a descriptor into the candidates worth a registration. A descriptor of the query robot
// (every robot's, offline) is searched among all keyframes once its keyframe is held here (it
// waits until then); a peer's descriptor (a robot's service) is searched among this robot's own
// keyframes instead (a reverse search), so that places both robots saw are found whichever robot
// passed first. Same-robot candidates the robot's own odometry puts far away are left out
// (IntraGate). A keyframe held here is also described from beside itself (LoopParams::lane_views_m):
// its forward search looks with those views too, and they enter the database, so that a peer's
// descriptor searched in reverse meets them; a match through a view starts verification from the
// view's offset. Synchronous, no I/O.
#pragma once

#include "cdc/lidar/scan_context.hpp"
#include "cdc/loop_closure/loop_types.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <vector>

namespace cdc::loops {

struct RetrievalStats {
  uint64_t queries = 0, candidates = 0;
  uint64_t duplicate_descriptors = 0, deferred_dropped = 0;
  uint64_t reverse_queries = 0;      // peers' descriptors searched among this robot's own keyframes
  uint64_t intra_gated = 0;          // same-robot candidates too far by the robot's odometry (not verified)
  uint64_t left_to_lower_robot = 0;  // candidates with a lower-numbered robot, verified by that robot
};

// Each robot's odometry chained from its first keyframe held here, to judge whether a same-robot
// loop is plausible: the two keyframes lie within gate_m + gate_per_m * (path driven between them).
// A keyframe after a gap in the chain has no chained pose, and any loop with it is plausible.
class IntraGate {
 public:
  IntraGate(double gate_m, double gate_per_m) : gate_m_(gate_m), gate_per_m_(gate_per_m) {}
  // A keyframe's odometry from the robot's previous keyframe (id - 1).
  void add(uint32_t robot, uint32_t id, const Eigen::Isometry3d& T_prev);
  bool plausible(const KeyframeId& query, const KeyframeId& candidate) const;

 private:
  struct Chained {
    Eigen::Isometry3d pose;  // in the robot's odometry frame (from its first keyframe here)
    double path_m = 0;       // distance driven since then
  };
  double gate_m_, gate_per_m_;  // gate_m_ 0: every loop is plausible
  std::set<uint32_t> started_;  // robots whose chain has begun
  std::map<KeyframeId, Chained> chained_;
};

class Retrieval {
 public:
  // `query_robot`: only this robot's descriptors start (forward) searches; none: every robot's.
  Retrieval(const LoopParams& params, std::optional<uint32_t> query_robot);

  // Whether the robot is a peer of the query robot (a robot's service only).
  bool is_peer(uint32_t robot) const { return query_robot_ && robot != *query_robot_; }
  // A keyframe's odometry, for the same-robot gate.
  void add_odometry(uint32_t robot, uint32_t id, const Eigen::Isometry3d& T_prev) { gate_.add(robot, id, T_prev); }

  // A query robot's descriptor whose keyframe is not held yet is searched once the keyframe comes.
  bool waits_for_keyframe(const DescriptorIn& d, bool keyframe_held) const;
  // Keeps it until take_deferred; beyond kMaxDeferred, the oldest enters the database unsearched.
  void defer(DescriptorIn d);
  std::optional<DescriptorIn> take_deferred(const KeyframeId& id);

  // The keyframe's views from beside it (taken with its forward search, then kept in the database).
  void add_views(const KeyframeId& id, std::vector<ShiftedView> views);

  // Marks the keyframe described; false (counted) when it was already.
  bool first_description(const KeyframeId& id);
  // Searches the descriptor (see the file comment), adds it to the database and returns the
  // candidates to verify, most similar first: within max_sc_distance, at most max_verify, none
  // left to a lower-numbered robot (lower_robot_verifies). `keyframe_held`: its keyframe is held here.
  std::vector<VerificationJob> search(DescriptorIn d, bool keyframe_held);

  size_t size() const noexcept { return db_.size(); }
  const lidar::ScanContextDatabase& database() const noexcept { return db_; }
  const RetrievalStats& stats() const noexcept { return stats_; }

  static constexpr size_t kMaxDeferred = 64;

 private:
  // A database match, and where the searched descriptor's sensor sits in its keyframe's frame.
  struct Match {
    lidar::ScanContextDatabase::Candidate found;
    Eigen::Vector3d searched_from = Eigen::Vector3d::Zero();
  };
  bool is_query_robot(uint32_t robot) const { return !query_robot_ || *query_robot_ == robot; }
  std::vector<Match> search_forward(const DescriptorIn& d);
  std::vector<Match> search_reverse(const DescriptorIn& d);
  // The best match per keyframe, most similar first.
  std::vector<Match> best_per_keyframe(std::vector<Match> matches) const;
  void add_to_database(const KeyframeId& id, lidar::ScanContext context,
                       const Eigen::Vector3d& sensor = Eigen::Vector3d::Zero());
  std::vector<VerificationJob> take_candidates(const std::vector<Match>& matches, const KeyframeId& me, bool reverse);

  LoopParams p_;
  std::optional<uint32_t> query_robot_;
  IntraGate gate_;
  lidar::ScanContextDatabase db_;
  std::vector<KeyframeId> owner_;                         // db id -> keyframe
  std::vector<Eigen::Vector3d> sensor_;                   // db id -> its (virtual) sensor in the keyframe's frame
  std::map<KeyframeId, std::vector<ShiftedView>> views_;  // views waiting for their keyframe's search
  std::set<KeyframeId> described_;                        // keyframes with a descriptor
  std::map<KeyframeId, DescriptorIn> deferred_;           // query descriptors waiting for their keyframe
  RetrievalStats stats_;
};

}  // namespace cdc::loops
