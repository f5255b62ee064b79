#include "loop_config.hpp"

#include "cdc/config/reader.hpp"

namespace cdc::loops {

LoopNodeOptions load_loop_options(const std::string& path) {
  LoopNodeOptions o;
  config::Reader r(path);
  auto positive_d = [](const double& v) { return v > 0; };
  auto positive_i = [](const int& v) { return v > 0; };
  const auto ms_of = [](Nanos t) { return static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(t).count()); };
  int robots = static_cast<int>(o.robots);
  r.get<int>("robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.robots = static_cast<uint32_t>(robots);
  LoopParams& p = o.core;
  r.get<int>("scan_context.rings", p.scan_context.rings, [](const int& v) { return v >= 1 && v <= 255; }, "1..255");
  r.get<int>("scan_context.sectors", p.scan_context.sectors, [](const int& v) { return v >= 4 && v <= 255; }, "4..255");
  r.get<double>("scan_context.max_range_m", p.scan_context.max_range_m, positive_d, "> 0");
  int knn = static_cast<int>(p.knn), verify = static_cast<int>(p.max_verify), recent = static_cast<int>(p.exclude_recent);
  int support = static_cast<int>(p.min_inter_support), cache = static_cast<int>(p.cloud_cache);
  r.get<int>("retrieval.knn", knn, positive_i, "> 0");
  int spacing = static_cast<int>(p.peer_request_spacing);
  r.get<int>("retrieval.peer_request_spacing", spacing, [](const int& v) { return v >= 0; }, ">= 0");
  p.peer_request_spacing = static_cast<uint32_t>(spacing);
  r.get<bool>("retrieval.lower_robot_verifies", p.lower_robot_verifies);
  r.get<double>("retrieval.reaim_max_m", p.reaim_max_m, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<double>("retrieval.max_sc_distance", p.max_sc_distance, [](const double& v) { return v > 0 && v <= 1; }, "(0, 1]");
  r.get<int>("retrieval.exclude_recent", recent, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>("retrieval.max_verify", verify, positive_i, "> 0");
  r.get<double>("retrieval.intra_gate_m", p.intra_gate_m, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<double>("retrieval.intra_gate_per_m", p.intra_gate_per_m, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<double>("verification.max_fitness_m2", p.max_fitness, positive_d, "> 0");
  r.get<double>("verification.min_overlap", p.min_overlap, [](const double& v) { return v > 0 && v <= 1; }, "(0, 1]");
  r.get<double>("verification.tilt_information_scale", p.tilt_information_scale,
                [](const double& v) { return v >= 0 && v <= 1; }, "0..1");
  r.get<double>("verification.voxel_m", p.registration.voxel_m, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<double>("verification.max_correspondence_m", p.registration.max_correspondence_m, positive_d, "> 0");
  r.get<int>("verification.max_iterations", p.registration.max_iterations, [](const int& v) { return v >= 1 && v <= 200; },
             "1..200");
  r.get<int>("verification.neighbours", p.registration.neighbours, [](const int& v) { return v >= 5 && v <= 100; }, "5..100");
  r.get<double>("verification.information_scale", p.registration.information_scale, positive_d, "> 0");
  r.get<double>("verification.loop_information_scale", p.loop_information_scale, positive_d, "> 0");
  r.get<double>("pcm.chi2_threshold", p.pcm.chi2_threshold, positive_d, "> 0");
  r.get<int>("pcm.min_support", support, positive_i, "> 0");
  int timeout = ms_of(p.request_timeout);
  r.get<int>("cloud_request_timeout_ms", timeout, positive_i, "> 0");
  r.get<int>("cloud_cache", cache, positive_i, "> 0");
  int prepared = static_cast<int>(p.prepared_clouds);
  r.get<int>("verification.prepared_clouds", prepared, [](const int& v) { return v >= 0 && v <= 1024; }, "0..1024");
  p.prepared_clouds = static_cast<size_t>(prepared);
  r.get<int>("cloud_request_attempts", p.request_attempts, positive_i, "> 0");
  int retry = ms_of(p.request_retry);
  r.get<int>("cloud_request_retry_ms", retry, positive_i, "> 0");
  p.request_retry = std::chrono::milliseconds(retry);
  int silence = ms_of(o.reach.silence), margin = ms_of(o.reach.margin), delay = ms_of(o.reach.delay);
  r.get<int>("peer_timeout_ms", silence, positive_i, "> 0");
  r.get<int>("loop_resend.margin_ms", margin, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>("loop_resend.delay_ms", delay, [](const int& v) { return v >= 0; }, ">= 0");
  int keep = static_cast<int>(o.reach.keep);
  r.get<int>("loop_resend.keep_loops", keep, positive_i, "> 0");
  o.reach = {std::chrono::milliseconds(silence), std::chrono::milliseconds(margin), std::chrono::milliseconds(delay),
             static_cast<size_t>(keep)};
  r.get<int>("tick_ms", o.tick_ms, positive_i, "> 0");
  int resend = ms_of(o.sequencer.resend);
  r.get<int>("descriptor_sync.resend_ms", resend, positive_i, "> 0");
  o.sequencer.resend = std::chrono::milliseconds(resend);
  r.get<int>("descriptor_sync.max_attempts", o.sequencer.max_attempts, positive_i, "> 0");
  r.get<float>("verification.reply_resolution_m", o.reply_resolution_m,
               [](const float& v) { return v > 0.0f && v <= 0.1f; }, "(0, 0.1]");
  r.get<std::string>("log_level", o.log_level);
  r.finish();
  p.knn = static_cast<size_t>(knn);
  p.max_verify = static_cast<size_t>(verify);
  p.exclude_recent = static_cast<uint32_t>(recent);
  p.min_inter_support = static_cast<size_t>(support);
  p.cloud_cache = static_cast<size_t>(cache);
  p.request_timeout = std::chrono::milliseconds(timeout);
  return o;
}

}  // namespace cdc::loops
