#include "peer_options.hpp"

#include "cdc/config/reader.hpp"

#include <cmath>

namespace cdc::peer {

PeerNodeOptions load_options(const std::string& path) {
  PeerNodeOptions o;
  config::Reader r(path);
  auto positive_d = [](const double& v) { return v > 0; };
  auto positive_i = [](const int& v) { return v > 0; };
  int robots = static_cast<int>(o.core.robot_count);
  r.get<int>(
      "robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.core.robot_count = static_cast<uint32_t>(robots);
  r.get<double>("range_m", o.core.rtdos.range_m, positive_d, "> 0");
  r.get<double>(
      "hysteresis_m", o.core.rtdos.hysteresis_m, [](const double& v) { return v >= 0; }, ">= 0");
  // Keys left out keep the core's defaults (PeerConfig, RtdosConfig): one place for each.
  const auto ms = [](Nanos d) {
    return static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(d).count());
  };
  int dwell = ms(o.core.rtdos.dwell), mask = ms(o.core.rtdos.mask), round = ms(o.core.round_period);
  int flap_window = ms(o.core.rtdos.flap_window), max_dwell_factor = static_cast<int>(o.core.rtdos.max_dwell_factor);
  int grace = ms(o.core.resend_grace), resend = ms(o.core.resend_period), refresh = ms(o.core.separator_refresh);
  r.get<int>(
      "dwell_ms", dwell, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>(
      "mask_ms", mask, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>(
      "flap_window_ms", flap_window, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>(
      "max_dwell_factor", max_dwell_factor, [](const int& v) { return v >= 1 && v <= 64; }, "1..64");
  r.get<int>("round_period_ms", round, positive_i, "> 0");
  r.get<int>(
      "resend_grace_ms", grace, [](const int& v) { return v >= 0; }, ">= 0");
  r.get<int>("resend_period_ms", resend, positive_i, "> 0");
  r.get<int>("separator_refresh_ms", refresh, positive_i, "> 0");
  o.core.rtdos.dwell = std::chrono::milliseconds(dwell);
  o.core.rtdos.mask = std::chrono::milliseconds(mask);
  o.core.rtdos.flap_window = std::chrono::milliseconds(flap_window);
  o.core.rtdos.max_dwell_factor = static_cast<uint32_t>(max_dwell_factor);
  o.core.round_period = std::chrono::milliseconds(round);
  o.core.resend_grace = std::chrono::milliseconds(grace);
  o.core.resend_period = std::chrono::milliseconds(resend);
  o.core.separator_refresh = std::chrono::milliseconds(refresh);
  r.get<double>("peer_range_m", o.core.peer_range_m, positive_d, "> 0");
  r.get<int>("distributed_iterations", o.core.distributed_iterations, positive_i, "> 0");
  r.get<double>(
      "distributed_relaxation", o.core.relaxation, [](const double& v) { return v > 0 && v <= 1; }, "in (0, 1]");
  r.get<bool>("share_loop_information", o.core.share_loop_information);
  const auto non_negative_d = [](const double& v) { return v >= 0; };
  r.get<double>("separator_min_change_m", o.core.separator_min_change_m, non_negative_d, ">= 0");
  double sep_deg = o.core.separator_min_change_rad * 180.0 / M_PI;
  r.get<double>("separator_min_change_deg", sep_deg, non_negative_d, ">= 0");
  o.core.separator_min_change_rad = sep_deg * M_PI / 180.0;
  r.get<double>("fusion.pos_max_m", o.core.fusion.pos_max, positive_d, "> 0");
  double rot_deg = o.core.fusion.rot_max * 180.0 / M_PI;
  r.get<double>("fusion.rot_max_deg", rot_deg, positive_d, "> 0");
  o.core.fusion.rot_max = rot_deg * M_PI / 180.0;
  int central_id = static_cast<int>(o.central_id);
  r.get<int>(
      "central_id", central_id, [](const int& v) { return v >= 0 && v <= 254; }, "0..254");
  o.central_id = static_cast<uint32_t>(central_id);
  r.get<int>("tick_ms", o.tick_ms, positive_i, "> 0");
  r.get<int>("status_period_ms", o.status_period_ms, positive_i, "> 0");
  r.get<int>("radio_status_period_ms", o.radio_status_period_ms, positive_i, "> 0");
  r.get<std::string>("log_level", o.log_level);
  if (o.core.rtdos.hysteresis_m >= o.core.rtdos.range_m) {
    r.error("hysteresis_m must be smaller than range_m");
  }
  r.finish();
  return o;
}

}  // namespace cdc::peer
