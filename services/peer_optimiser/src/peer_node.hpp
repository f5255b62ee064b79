// DDS shell of the peer optimiser: the robot's keyframes and loops, the central's results,
// acknowledgements and liveliness, peers' separator poses and statuses in; mode, corrections
// (to the front-end), separator poses, the robot's world transform, re-sends and status out.
// The decisions are PeerCore's.
#pragma once

#include "mode_files.hpp"
#include "own_records.hpp"
#include "peer_messages.hpp"
#include "peer_options.hpp"
#include "period.hpp"

#include "cdc/dds/liveliness.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/dds/waitset.hpp"
#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <optional>
#include <string>
#include <vector>

namespace cdc::peer {

// The node's own counters beside the state it reports (PeerNodeState).
struct PeerNodeCounters {
  uint64_t forwarded_keyframes = 0;  // own keyframes sent on to the central (CENTRALIZED)
  uint64_t withheld_keyframes = 0;   // ... and kept back (DISTRIBUTED; they go with the backlog)
  uint64_t keyframe_writer_discards = 0;
  uint64_t resent_keyframes = 0, resent_loops = 0;             // the backlog the central had not acknowledged
  uint64_t forwarded_cloud_bytes = 0, resent_cloud_bytes = 0;  // packed clouds (KeyframeCloud payload) [B]
  uint64_t cloud_points_dropped = 0;  // points beyond the packing's int16 grid (compact::PackedCloud::dropped)
  uint64_t corrections = 0, separator_messages = 0;
};

// The robot's back-end at shutdown, as --stats-out reports it.
struct PeerNodeState {
  uint32_t robot = 0;
  std::string mode;
  uint32_t transitions = 0;
  uint64_t keyframes = 0, distributed_rounds = 0, radio_cuts = 0;
  uint64_t keyframes_duplicate = 0, keyframes_refused = 0;  // own keyframes not taken (PeerCore::add_keyframe)
  uint64_t coarse_steps = 0;                                // distributed rounds that began with a coarse step
  uint64_t own_loops_held_out = 0;                          // own loops the last distributed round's GNC held out
  uint64_t separator_poses = 0, relayed_loops = 0;          // sent to peers (cdc/peer/separator)
};

class PeerNode {
 public:
  PeerNode(const runtime::ServiceOptions& common, const PeerNodeOptions& options);
  ~PeerNode();
  PeerNode(const PeerNode&) = delete;
  PeerNode& operator=(const PeerNode&) = delete;

  // Works until shutdown is asked for.
  void spin();
  // State and counters, as --stats-out writes them.
  nlohmann::json stats() const;
  // Writes --trajectory-out, --graph-out and --stats-out.
  void finish() const;

 private:
  using Clock = std::chrono::steady_clock;

  void wire_inputs();
  void on_keyframe(const cdc_msg_Keyframe& m);
  uint64_t send_keyframe(const OwnKeyframe& k, dds::compact::PackedCloud& packed, bool with_keyframe);
  void on_loop(const cdc_msg_LoopClosure& m);
  void on_central_result(const cdc_msg_OptimizedPoses& m);
  void on_ack(const cdc_msg_Acknowledgement& m);
  void on_separator(const cdc_msg_SeparatorPoses& m);
  void on_status(const cdc_msg_RobotStatus& m);
  void take_inputs();
  void notice_rematched_peers();
  void step();
  // drop_undelivered_keyframes: the core's word that keyframes forwarded but not delivered go with the backlog.
  void on_transition(const Transition& t, bool central_alive, bool drop_undelivered_keyframes);
  void publish_mode(SwitchReason reason, std::optional<double> distance);
  void resend(const StepOutput& out);
  void publish_separators(const std::vector<SeparatorOut>& separators);
  void publish_correction(const Correction& c);
  void log_correction(const Correction& c) const;
  void publish_status(bool central_alive);
  void write_now(bool central_alive) const;
  Origin origin() const;
  Nanos elapsed() const { return std::chrono::duration_cast<Nanos>(Clock::now() - t0_); }

  PeerNodeOptions o_;
  runtime::Service service_;
  runtime::Input<cdc_msg_Keyframe> keyframes_;
  runtime::Input<cdc_msg_LoopClosure> loops_;
  std::optional<runtime::Input<cdc_msg_LoopClosure>> local_loops_;  // with a local domain
  runtime::Input<cdc_msg_OptimizedPoses> central_results_;
  runtime::Input<cdc_msg_Acknowledgement> acks_;
  runtime::Input<cdc_msg_SeparatorPoses> separators_;
  runtime::Input<cdc_msg_RobotStatus> statuses_;
  dds::Topic<cdc_msg_SeparatorPoses> t_sep_;
  dds::Topic<cdc_msg_RobotStatus> t_alive_;
  dds::TopicWriter<cdc_msg_ModeState> w_mode_;
  dds::TopicWriter<cdc_msg_OptimizedPoses> w_corr_;
  dds::PerRobotWriters<cdc_msg_SeparatorPoses> w_sep_;
  dds::TopicWriter<cdc_msg_WorldTransform> w_world_;
  dds::TopicWriter<cdc_msg_KeyframeSequence> w_sequence_;
  dds::TopicWriter<cdc_msg_Keyframe> w_kf_;
  dds::TopicWriter<cdc_msg_KeyframeCloud> w_cloud_;
  dds::TopicWriter<cdc_msg_LoopClosure> w_loop_;
  dds::TopicWriter<cdc_msg_RobotStatus> w_status_;
  dds::GuardCondition liveliness_changed_;
  dds::LivelinessMonitor central_;

  const Clock::time_point t0_ = Clock::now();
  PeerCore core_;
  Nanos now_{0};  // of the current pass
  OwnRecords records_;
  ModeFiles mode_files_;
  PeerNodeCounters counters_;
  uint32_t incarnation_ = 0;
  int64_t sim_stamp_ns_ = 0;                 // newest own keyframe's data time
  std::vector<uint32_t> separator_matches_;  // per peer: its readers ever matched
  Period mode_period_, radio_status_period_, status_file_period_;
  std::vector<cdc_msg_KeyframePose> pose_storage_;
  SeparatorStorage separator_storage_;
};

}  // namespace cdc::peer
