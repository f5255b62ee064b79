#include "loop_config.hpp"

#include "cdc/config/reader.hpp"

#include <chrono>
#include <functional>
#include <string>

namespace cdc::loops {
namespace {

using config::Reader;
using IntCheck = std::function<bool(const int&)>;

const auto positive = [](const auto& v) { return v > 0; };
const auto non_negative = [](const auto& v) { return v >= 0; };
const auto fraction = [](const double& v) { return v > 0 && v <= 1; };  // (0, 1]

// A count (unsigned in the options) read as an int.
template <class Count>
void get_count(Reader& r, const std::string& key, Count& out, const IntCheck& valid, const std::string& expectation) {
  int v = static_cast<int>(out);
  r.get<int>(key, v, valid, expectation);
  out = static_cast<Count>(v);
}

// A duration read in milliseconds.
void get_ms(Reader& r, const std::string& key, Nanos& out, const IntCheck& valid, const std::string& expectation) {
  int v = static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(out).count());
  r.get<int>(key, v, valid, expectation);
  out = std::chrono::milliseconds(v);
}

void read_scan_context(Reader& r, lidar::ScanContextParams& p) {
  r.get<int>(
      "scan_context.rings", p.rings, [](const int& v) { return v >= 1 && v <= 255; }, "1..255");
  r.get<int>(
      "scan_context.sectors", p.sectors, [](const int& v) { return v >= 4 && v <= 255; }, "4..255");
  r.get<double>("scan_context.max_range_m", p.max_range_m, positive, "> 0");
}

void read_retrieval(Reader& r, LoopParams& p) {
  get_count(r, "retrieval.knn", p.knn, positive, "> 0");
  get_count(r, "retrieval.peer_request_spacing", p.peer_request_spacing, non_negative, ">= 0");
  r.get<bool>("retrieval.lower_robot_verifies", p.lower_robot_verifies);
  r.get<double>("retrieval.reaim_max_m", p.reaim_max_m, non_negative, ">= 0");
  r.get<double>("retrieval.max_sc_distance", p.max_sc_distance, fraction, "(0, 1]");
  get_count(r, "retrieval.exclude_recent", p.exclude_recent, non_negative, ">= 0");
  get_count(r, "retrieval.max_verify", p.max_verify, positive, "> 0");
  r.get<double>("retrieval.intra_gate_m", p.intra_gate_m, non_negative, ">= 0");
  r.get<double>("retrieval.intra_gate_per_m", p.intra_gate_per_m, non_negative, ">= 0");
}

void read_verification(Reader& r, LoopParams& p) {
  r.get<double>("verification.max_fitness_m2", p.max_fitness, positive, "> 0");
  r.get<double>("verification.min_overlap", p.min_overlap, fraction, "(0, 1]");
  r.get<double>(
      "verification.tilt_information_scale", p.tilt_information_scale, [](const double& v) { return v >= 0 && v <= 1; },
      "0..1");
  r.get<double>("verification.voxel_m", p.registration.voxel_m, non_negative, ">= 0");
  r.get<double>("verification.max_correspondence_m", p.registration.max_correspondence_m, positive, "> 0");
  r.get<int>(
      "verification.max_iterations", p.registration.max_iterations, [](const int& v) { return v >= 1 && v <= 200; },
      "1..200");
  r.get<int>(
      "verification.neighbours", p.registration.neighbours, [](const int& v) { return v >= 5 && v <= 100; }, "5..100");
  r.get<double>("verification.information_scale", p.registration.information_scale, positive, "> 0");
  r.get<double>("verification.loop_information_scale", p.loop_information_scale, positive, "> 0");
}

void read_pcm(Reader& r, LoopParams& p) {
  r.get<double>("pcm.chi2_threshold", p.pcm.chi2_threshold, positive, "> 0");
  get_count(r, "pcm.min_support", p.min_inter_support, positive, "> 0");
}

// Cloud requests, and the clouds kept.
void read_clouds(Reader& r, LoopParams& p) {
  get_ms(r, "cloud_request_timeout_ms", p.request_timeout, positive, "> 0");
  get_count(r, "cloud_cache", p.cloud_cache, positive, "> 0");
  get_count(
      r, "verification.prepared_clouds", p.prepared_clouds, [](const int& v) { return v >= 0 && v <= 1024; },
      "0..1024");
  r.get<int>("cloud_request_attempts", p.request_attempts, positive, "> 0");
  get_ms(r, "cloud_request_retry_ms", p.request_retry, positive, "> 0");
}

// The node's own: peers in reach and loops written again, the pass, missed descriptors, replies.
void read_node(Reader& r, LoopNodeOptions& o) {
  get_ms(r, "peer_timeout_ms", o.reach.silence, positive, "> 0");
  get_ms(r, "loop_resend.margin_ms", o.reach.margin, non_negative, ">= 0");
  get_ms(r, "loop_resend.delay_ms", o.reach.delay, non_negative, ">= 0");
  get_count(r, "loop_resend.keep_loops", o.reach.keep, positive, "> 0");
  r.get<int>("tick_ms", o.tick_ms, positive, "> 0");
  get_ms(r, "descriptor_sync.resend_ms", o.sequencer.resend, positive, "> 0");
  r.get<int>("descriptor_sync.max_attempts", o.sequencer.max_attempts, positive, "> 0");
  r.get<float>(
      "verification.reply_resolution_m", o.reply_resolution_m, [](const float& v) { return v > 0.0f && v <= 0.1f; },
      "(0, 0.1]");
  r.get<std::string>("log_level", o.log_level);
}

}  // namespace

LoopNodeOptions load_loop_options(const std::string& path) {
  LoopNodeOptions o;
  Reader r(path);
  get_count(
      r, "robots", o.robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  read_scan_context(r, o.core.scan_context);
  read_retrieval(r, o.core);
  read_verification(r, o.core);
  read_pcm(r, o.core);
  read_clouds(r, o.core);
  read_node(r, o);
  r.finish();
  return o;
}

}  // namespace cdc::loops
