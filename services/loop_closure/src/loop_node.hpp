// DDS shell of the loop-closure service: the robot's keyframes and every robot's descriptors in;
// cloud requests and replies between owners, descriptor resend requests and loop closures out. The
// search, verification and PCM are LoopCore's; the order descriptors are searched in is the
// sequencer's and the search queue's; which peers are in reach, and which loops they may have
// missed, PeerReach's.
#pragma once

#include "backlog_file.hpp"
#include "loop_config.hpp"
#include "loop_node_stats.hpp"
#include "peer_traffic.hpp"
#include "written_loops.hpp"

#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/loop_closure/loop_numbering.hpp"
#include "cdc/loop_closure/search_queue.hpp"
#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <chrono>
#include <optional>
#include <vector>

namespace cdc::loops {

class LoopNode {
 public:
  LoopNode(const runtime::ServiceOptions& common, const LoopNodeOptions& options);
  // Works until shutdown is asked for.
  void spin();
  // Core and node counters, as --stats-out writes them.
  nlohmann::json stats() const;
  // Writes --stats-out.
  void finish() const;

 private:
  void wire_inputs();
  void log_start() const;

  void on_status(const cdc_msg_RobotStatus& m);
  void on_cloud_request(const cdc_msg_CloudRequest& m);
  void on_keyframe(const cdc_msg_Keyframe& m);
  void on_descriptor(const cdc_msg_Descriptor& m);
  void on_cloud_reply(const cdc_msg_CloudReply& m);
  void poll_descriptors();
  void ask_for_missed_descriptors();
  void search_next();

  void handle(LoopEvents events);
  void request_clouds(const std::vector<CloudWanted>& wanted);
  void publish(const LoopOut& loop);
  void write_loop(const cdc_msg_LoopClosure& m);
  void write_loops_again();
  uint32_t next_loop_seq();
  Backlog backlog() const;

  // Time since the node started (the core's clock).
  Nanos clock() const;
  bool in_reach(uint32_t robot) const;

  LoopNodeOptions o_;
  std::chrono::steady_clock::time_point t0_;
  Nanos now_{0};  // clock() at the start of the current pass
  runtime::Service service_;
  runtime::Input<cdc_msg_RobotStatus> status_;
  runtime::Input<cdc_msg_CloudRequest> requests_;
  runtime::Input<cdc_msg_Keyframe> keyframes_;
  runtime::Input<cdc_msg_Descriptor> descriptors_;
  runtime::Input<cdc_msg_Descriptor> descriptors_resent_;
  std::optional<runtime::Input<cdc_msg_Descriptor>> descriptors_local_;
  runtime::Input<cdc_msg_CloudReply> replies_;
  dds::Topic<cdc_msg_CloudReply> t_rep_;
  dds::TopicWriter<cdc_msg_LoopClosure> w_loop_;
  dds::PerRobotWriters<cdc_msg_LoopClosure> w_loop_with_;
  std::optional<dds::TopicWriter<cdc_msg_LoopClosure>> w_loop_local_;
  dds::TopicWriter<cdc_msg_CloudRequest> w_req_;
  dds::PerRobotWriters<cdc_msg_CloudReply> w_rep_to_;
  dds::TopicWriter<cdc_msg_DescriptorSync> w_sync_;

  LoopCore core_;
  DescriptorSequencer sequencer_;
  SearchQueue to_search_;  // delivered in order by the sequencer, searched one per pass, robots in turn
  PeerReach reach_;
  WrittenLoops written_;
  LoopNumbering numbering_;
  uint64_t numbering_failures_logged_ = 0;
  BacklogFile backlog_file_;
  PeerTraffic traffic_;
  LoopNodeCounters counters_;
  std::vector<double> latencies_s_;  // published loops: from the later descriptor coming in
  uint32_t incarnation_ = 0;
  uint64_t next_request_ = 1;
};

}  // namespace cdc::loops
