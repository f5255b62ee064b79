// DDS shell of the central optimiser: validated keyframes, loops and world hints in; optimised poses
// (liveliness-monitored writer, asserted while the work loop progresses), acknowledgements and the central's
// status out. The graph is CentralCore's.
#pragma once

#include "central_config.hpp"

#include "cdc/central_optimiser/central_core.hpp"
#include "cdc/central_optimiser/update_schedule.hpp"
#include "cdc/dds/pubsub.hpp"
#include "cdc/dds/types.hpp"
#include "cdc/runtime/input.hpp"
#include "cdc/runtime/options.hpp"
#include "cdc/runtime/service.hpp"

#include <nlohmann/json.hpp>

#include <atomic>
#include <chrono>
#include <deque>
#include <optional>
#include <thread>
#include <vector>

namespace cdc::central {

class CentralNode {
 public:
  CentralNode(const runtime::ServiceOptions& common, const CentralNodeOptions& options);
  ~CentralNode();
  CentralNode(const CentralNode&) = delete;
  CentralNode& operator=(const CentralNode&) = delete;
  // Works until shutdown is asked for.
  void spin();
  // The final optimisation over the whole graph, then --graph-out and --stats-out.
  void finish();
  nlohmann::json stats(double final_cost) const;

 private:
  void take_inputs();
  void progressed() { progress_ns_.store(std::chrono::steady_clock::now().time_since_epoch().count()); }
  void watch();
  void on_keyframe(const cdc_msg_Keyframe& m);
  void on_loop(const cdc_msg_LoopClosure& m);
  void on_world(const cdc_msg_WorldTransform& m);
  void optimise(UpdateSchedule::Clock::time_point now);
  void publish_due_results(UpdateSchedule::Clock::time_point now);
  void publish_result(const RobotEstimate& e);
  void publish_acknowledgements();
  void publish_status();
  std::optional<Eigen::Vector3d> position() const;
  nlohmann::json reader_losses() const;
  void record_update_time(double ms);
  nlohmann::json update_times() const;

  CentralNodeOptions o_;
  uint32_t incarnation_;
  runtime::Service service_;
  runtime::Input<cdc_msg_Keyframe> keyframes_;
  runtime::Input<cdc_msg_LoopClosure> loops_;
  runtime::Input<cdc_msg_WorldTransform> world_;
  dds::Topic<cdc_msg_OptimizedPoses> t_opt_;
  dds::TopicWriter<cdc_msg_RobotStatus> w_alive_;
  std::deque<dds::Writer<cdc_msg_OptimizedPoses>> w_results_;  // one per robot, in the robot's partition
  dds::TopicWriter<cdc_msg_Acknowledgement> w_ack_;
  dds::TopicWriter<cdc_msg_RobotStatus> w_status_;

  CentralCore core_;
  UpdateSchedule schedule_;
  ResultPacer pacer_;
  UpdateSchedule::Clock::time_point last_status_;
  bool acks_dirty_ = false;
  std::vector<cdc_msg_KeyframePose> pose_storage_;
  static constexpr size_t kUpdateTimesKept = 4096;
  std::vector<double> update_ms_;        // wall time of the most recent updates [ms]
  std::atomic<int64_t> progress_ns_{0};  // steady clock at the work loop's latest progress
  std::atomic<bool> stopping_{false};
  std::thread watchdog_;  // asserts liveliness while the work loop progresses (declared last: started last)
};

}  // namespace cdc::central
