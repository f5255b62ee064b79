#include "loop_config.hpp"

#include "cdc/config/reader.hpp"
#include "cdc/config/scan_context.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

namespace cdc::loops {
namespace {

using config::Reader;

constexpr int kHourMs = 3'600'000;

// A duration read in milliseconds, in [lo, hi].
void get_ms(Reader& r, const std::string& key, Nanos& out, int lo, int hi) {
  int v = static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(out).count());
  r.get_in(key, v, lo, hi);
  out = std::chrono::milliseconds(v);
}

void read_retrieval(Reader& r, LoopParams& p) {
  r.get_count("retrieval.knn", p.knn, 1, 1000);
  r.get<std::vector<double>>(
      "retrieval.lane_views_m", p.lane_views_m,
      [](const std::vector<double>& v) {
        return v.size() <= 8 && std::all_of(v.begin(), v.end(), [](double y) { return y != 0 && std::abs(y) <= 20; });
      },
      "at most 8 offsets, each nonzero and within [-20, 20] m");
  r.get_count("retrieval.peer_request_spacing", p.peer_request_spacing, 0, 100000);
  r.get<bool>("retrieval.lower_robot_verifies", p.lower_robot_verifies);
  r.get_in("retrieval.reaim_max_m", p.reaim_max_m, 0.0, 1000.0);
  r.get_in("retrieval.max_sc_distance", p.max_sc_distance, 0.001, 1.0);
  r.get_count("retrieval.exclude_recent", p.exclude_recent, 0, 100000);
  r.get_count("retrieval.max_verify", p.max_verify, 1, 1000);
  r.get_in("retrieval.intra_gate_m", p.intra_gate_m, 0.0, 1000.0);
  r.get_in("retrieval.intra_gate_per_m", p.intra_gate_per_m, 0.0, 10.0);
}

void read_verification(Reader& r, LoopParams& p) {
  r.get_in("verification.ground_guess_min_m", p.ground_guess_min_m, 0.0, 1000.0);
  r.get_in("verification.max_fitness_m2", p.max_fitness, 1e-6, 100.0);
  r.get_in("verification.min_overlap", p.min_overlap, 0.001, 1.0);
  r.get_in("verification.tilt_information_scale", p.tilt_information_scale, 0.0, 1.0);
  r.get_in("verification.voxel_m", p.registration.voxel_m, 0.0, 10.0);
  r.get_in("verification.max_correspondence_m", p.registration.max_correspondence_m, 0.01, 100.0);
  r.get_in("verification.max_iterations", p.registration.max_iterations, 1, 200);
  r.get_in("verification.neighbours", p.registration.neighbours, 5, 100);
  r.get_in("verification.information_scale", p.registration.information_scale, 1e-6, 1e6);
  r.get_in("verification.loop_information_scale", p.loop_information_scale, 1e-6, 1e6);
}

void read_pcm(Reader& r, LoopParams& p) {
  r.get_in("pcm.chi2_threshold", p.pcm.chi2_threshold, 0.01, 1e6);
  r.get_count("pcm.min_support", p.min_inter_support, 1, 1000);
}

// Cloud requests, and the clouds kept.
void read_clouds(Reader& r, LoopParams& p) {
  get_ms(r, "cloud_request_timeout_ms", p.request_timeout, 1, kHourMs);
  r.get_count("cloud_cache", p.cloud_cache, 1, 100000);
  r.get_count("verification.prepared_clouds", p.prepared_clouds, 0, 1024);
  r.get_in("cloud_request_attempts", p.request_attempts, 1, 1000);
  get_ms(r, "cloud_request_retry_ms", p.request_retry, 1, kHourMs);
}

// The node's own: peers in reach and loops written again, the pass, missed descriptors, replies.
void read_node(Reader& r, LoopNodeOptions& o) {
  get_ms(r, "peer_timeout_ms", o.reach.silence, 1, kHourMs);
  get_ms(r, "loop_resend.margin_ms", o.reach.margin, 0, kHourMs);
  get_ms(r, "loop_resend.delay_ms", o.reach.delay, 0, kHourMs);
  r.get_count("loop_resend.keep_loops", o.reach.keep, 1, 1000000);
  r.get_in("tick_ms", o.tick_ms, 1, 60000);
  get_ms(r, "descriptor_sync.resend_ms", o.sequencer.resend, 1, kHourMs);
  r.get_in("descriptor_sync.max_attempts", o.sequencer.max_attempts, 1, 1000);
  r.get_in("verification.reply_resolution_m", o.reply_resolution_m, 1e-6f, 0.1f);
  r.get<std::string>("log_level", o.log_level);
}

}  // namespace

LoopNodeOptions load_loop_options(const std::string& path) {
  LoopNodeOptions o;
  Reader r(path);
  r.get_count("robots", o.robots, 1, 254);
  config::read_scan_context(r, o.core.scan_context);
  read_retrieval(r, o.core);
  read_verification(r, o.core);
  read_pcm(r, o.core);
  read_clouds(r, o.core);
  read_node(r, o);
  r.finish();
  return o;
}

}  // namespace cdc::loops
