#include "loop_node_stats.hpp"

#include "cdc/geometry/metrics.hpp"

namespace cdc::loops {

CoreCounters core_counters(const LoopStats& s) {
  return {.queries = s.queries,
          .reverse_queries = s.reverse_queries,
          .intra_gated = s.intra_gated,
          .skipped_near_requested = s.skipped_near_requested,
          .left_to_lower_robot = s.left_to_lower_robot,
          .verified_with_neighbour = s.verified_with_neighbour,
          .reaim_too_far = s.reaim_too_far,
          .clouds_prepared = s.prepared,
          .prepared_clouds_reused = s.prepared_reused,
          .verified = s.verified,
          .verification_failed = s.verification_failed,
          .verification_failed_by = {s.failed_not_converged, s.failed_fitness, s.failed_overlap},
          .intra_accepted = s.intra_accepted,
          .inter_accepted = s.inter_accepted,
          .withdrawn = s.withdrawn,
          .cloud_requests = s.requests,
          .cloud_replies = s.replies,
          .cloud_missing = s.missing,
          .cloud_timed_out = s.timed_out,
          .cloud_requests_retried = s.requests_retried,
          .cloud_requests_abandoned = s.requests_abandoned,
          .cloud_unreachable = s.unreachable};
}

SequencerCounters sequencer_counters(const SequencerStats& s) {
  return {s.sync_requests, s.duplicates, s.gaps_skipped, s.ids_skipped};
}

ReachCounters reach_counters(const PeerReachStats& s) { return {s.silences, s.loops_due, s.forgotten}; }

NumberingCounters numbering_counters(const LoopNumberingStats& s, const std::string& state_file) {
  return {state_file, s.resumed, s.state_errors, s.save_failures};
}

LatencySummary latency_summary(const std::vector<double>& seconds) {
  const geometry::ErrorStats st = geometry::compute_stats(seconds);
  return {st.count, st.median, st.p90, st.max};
}

}  // namespace cdc::loops
