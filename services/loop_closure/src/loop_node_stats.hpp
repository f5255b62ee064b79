// The loop-closure service's own part of its --stats-out document (what every service writes beside
// it is runtime/stats.hpp's): the node's counters and those of the core, the descriptor sequencer,
// the peers' reach and the loop numbering, under the names the launcher's report and the tests read.
// No DDS.
#pragma once

#include "cdc/loop_closure/descriptor_sequencer.hpp"
#include "cdc/loop_closure/loop_core.hpp"
#include "cdc/loop_closure/loop_numbering.hpp"
#include "cdc/loop_closure/peer_reach.hpp"

#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace cdc::loops {

// Counted by the node itself.
struct LoopNodeCounters {
  uint64_t loops_published = 0;            // loop messages written: accepted loops and withdrawals
  uint64_t requests_served = 0;            // peers' cloud requests answered with the cloud
  uint64_t points_served = 0;              // the points of those clouds
  uint64_t requests_unknown_keyframe = 0;  // peers' cloud requests for a keyframe this robot does not hold
  uint64_t cloud_replies_duplicate = 0;    // the answer to both attempts of a request asked again: one was used
  uint64_t descriptors_waiting_peak = 0;   // most descriptors waiting to be searched at once
};

// Why verifications failed (LoopStats::failed_*).
struct VerificationFailures {
  uint64_t not_converged = 0, fitness = 0, overlap = 0;
};

// The core's counters (LoopStats).
struct CoreCounters {
  uint64_t queries = 0, reverse_queries = 0, intra_gated = 0, skipped_near_requested = 0, left_to_lower_robot = 0;
  uint64_t verified_with_neighbour = 0, reaim_too_far = 0, clouds_prepared = 0, prepared_clouds_reused = 0;
  uint64_t verified = 0, verification_failed = 0;
  VerificationFailures verification_failed_by;
  uint64_t intra_accepted = 0, inter_accepted = 0, withdrawn = 0;
  uint64_t cloud_requests = 0, cloud_replies = 0, cloud_missing = 0, cloud_timed_out = 0;
  uint64_t cloud_requests_retried = 0, cloud_requests_abandoned = 0, cloud_unreachable = 0;
};
CoreCounters core_counters(const LoopStats& s);

// The descriptor sequencer's (SequencerStats).
struct SequencerCounters {
  uint64_t descriptor_sync_requests = 0, descriptor_duplicates = 0, descriptor_gaps_skipped = 0;
  uint64_t descriptor_ids_skipped = 0;
};
SequencerCounters sequencer_counters(const SequencerStats& s);

// The peers' reach and the loops written again (PeerReachStats).
struct ReachCounters {
  uint64_t peer_silences = 0, loops_written_again = 0, loops_forgotten = 0;
};
ReachCounters reach_counters(const PeerReachStats& s);

// The loop numbering and its state file (LoopNumberingStats).
struct NumberingCounters {
  std::string state_file;
  uint64_t resumed = 0, state_errors = 0, save_failures = 0;
};
NumberingCounters numbering_counters(const LoopNumberingStats& s, const std::string& state_file);

// Seconds from the later descriptor of a loop coming in to the loop going out.
struct LatencySummary {
  size_t count = 0;
  double median = 0, p90 = 0, max = 0;
};
LatencySummary latency_summary(const std::vector<double>& seconds);

NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(LoopNodeCounters, loops_published, requests_served, points_served,
                                   requests_unknown_keyframe, cloud_replies_duplicate, descriptors_waiting_peak)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(VerificationFailures, not_converged, fitness, overlap)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CoreCounters, queries, reverse_queries, intra_gated, skipped_near_requested,
                                   left_to_lower_robot, verified_with_neighbour, reaim_too_far, clouds_prepared,
                                   prepared_clouds_reused, verified, verification_failed, verification_failed_by,
                                   intra_accepted, inter_accepted, withdrawn, cloud_requests, cloud_replies,
                                   cloud_missing, cloud_timed_out, cloud_requests_retried, cloud_requests_abandoned,
                                   cloud_unreachable)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(SequencerCounters, descriptor_sync_requests, descriptor_duplicates,
                                   descriptor_gaps_skipped, descriptor_ids_skipped)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(ReachCounters, peer_silences, loops_written_again, loops_forgotten)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(NumberingCounters, state_file, resumed, state_errors, save_failures)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(LatencySummary, count, median, p90, max)

}  // namespace cdc::loops
