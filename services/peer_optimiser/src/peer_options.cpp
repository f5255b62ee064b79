#include "peer_options.hpp"

#include "cdc/config/reader.hpp"

#include <cmath>

namespace cdc::peer {

PeerNodeOptions load_options(const std::string& path) {
  PeerNodeOptions o;
  config::Reader r(path);
  constexpr int kHourMs = 3'600'000;
  constexpr double kUnlimitedM = 1e9;  // a range this long stands for "no limit" in the shipped files
  r.get_count("robots", o.core.robot_count, 1, 254);
  r.get_in("range_m", o.core.rtdos.range_m, 1.0, kUnlimitedM);
  r.get_in("hysteresis_m", o.core.rtdos.hysteresis_m, 0.0, kUnlimitedM);
  // Keys left out keep the core's defaults (PeerConfig, RtdosConfig): one place for each.
  const auto ms = [](Nanos d) {
    return static_cast<int>(std::chrono::duration_cast<std::chrono::milliseconds>(d).count());
  };
  int dwell = ms(o.core.rtdos.dwell), mask = ms(o.core.rtdos.mask), round = ms(o.core.round_period);
  int flap_window = ms(o.core.rtdos.flap_window), max_dwell_factor = static_cast<int>(o.core.rtdos.max_dwell_factor);
  int grace = ms(o.core.resend_grace), resend = ms(o.core.resend_period), refresh = ms(o.core.separator_refresh);
  r.get_in("dwell_ms", dwell, 0, kHourMs);
  r.get_in("mask_ms", mask, 0, kHourMs);
  r.get_in("flap_window_ms", flap_window, 0, kHourMs);
  r.get_in("max_dwell_factor", max_dwell_factor, 1, 64);
  r.get_in("round_period_ms", round, 1, kHourMs);
  r.get_in("resend_grace_ms", grace, 0, kHourMs);
  r.get_in("resend_period_ms", resend, 1, kHourMs);
  r.get_in("separator_refresh_ms", refresh, 1, kHourMs);
  o.core.rtdos.dwell = std::chrono::milliseconds(dwell);
  o.core.rtdos.mask = std::chrono::milliseconds(mask);
  o.core.rtdos.flap_window = std::chrono::milliseconds(flap_window);
  o.core.rtdos.max_dwell_factor = static_cast<uint32_t>(max_dwell_factor);
  o.core.round_period = std::chrono::milliseconds(round);
  o.core.resend_grace = std::chrono::milliseconds(grace);
  o.core.resend_period = std::chrono::milliseconds(resend);
  o.core.separator_refresh = std::chrono::milliseconds(refresh);
  r.get_in("peer_range_m", o.core.peer_range_m, 1.0, kUnlimitedM);
  r.get_in("distributed_iterations", o.core.distributed_iterations, 1, 1000);
  r.get_in("distributed_relaxation", o.core.relaxation, 1e-3, 1.0);
  r.get<bool>("share_loop_information", o.core.share_loop_information);
  r.get_in("own_loop_gnc_threshold", o.core.own_loop_gnc_threshold, 0.0, 1e9);
  r.get<bool>("coarse_step", o.core.coarse_step);
  r.get_in("separator_min_change_m", o.core.separator_min_change_m, 0.0, 100.0);
  double sep_deg = o.core.separator_min_change_rad * 180.0 / M_PI;
  r.get_in("separator_min_change_deg", sep_deg, 0.0, 180.0);
  o.core.separator_min_change_rad = sep_deg * M_PI / 180.0;
  r.get_in("fusion.pos_max_m", o.core.fusion.pos_max, 0.001, 1000.0);
  double rot_deg = o.core.fusion.rot_max * 180.0 / M_PI;
  r.get_in("fusion.rot_max_deg", rot_deg, 0.01, 180.0);
  o.core.fusion.rot_max = rot_deg * M_PI / 180.0;
  r.get_count("central_id", o.central_id, 0, 254);
  r.get_in("map_cloud_resolution_m", o.map_cloud_resolution_m, 0.001f, 0.5f);
  r.get_in("tick_ms", o.tick_ms, 1, 60000);
  r.get_in("status_period_ms", o.status_period_ms, 1, 60000);
  r.get_in("radio_status_period_ms", o.radio_status_period_ms, 1, 60000);
  r.get<std::string>("log_level", o.log_level);
  if (o.core.rtdos.hysteresis_m >= o.core.rtdos.range_m) {
    r.error("hysteresis_m must be smaller than range_m");
  }
  r.finish();
  return o;
}

}  // namespace cdc::peer
