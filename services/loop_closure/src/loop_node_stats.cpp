#include "loop_node_stats.hpp"

#include "cdc/geometry/metrics.hpp"

namespace cdc::loops {

CoreCounters core_counters(const LoopStats& s) {
  CoreCounters c;
  c.queries = s.queries;
  c.reverse_queries = s.reverse_queries;
  c.intra_gated = s.intra_gated;
  c.skipped_near_requested = s.skipped_near_requested;
  c.left_to_lower_robot = s.left_to_lower_robot;
  c.verified_with_neighbour = s.verified_with_neighbour;
  c.reaim_too_far = s.reaim_too_far;
  c.clouds_prepared = s.prepared;
  c.prepared_clouds_reused = s.prepared_reused;
  c.verified = s.verified;
  c.verification_failed = s.verification_failed;
  c.verification_failed_by = {s.failed_not_converged, s.failed_fitness, s.failed_overlap};
  c.intra_accepted = s.intra_accepted;
  c.inter_accepted = s.inter_accepted;
  c.withdrawn = s.withdrawn;
  c.cloud_requests = s.requests;
  c.cloud_replies = s.replies;
  c.cloud_missing = s.missing;
  c.cloud_timed_out = s.timed_out;
  c.cloud_requests_retried = s.requests_retried;
  c.cloud_requests_abandoned = s.requests_abandoned;
  c.cloud_unreachable = s.unreachable;
  return c;
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
