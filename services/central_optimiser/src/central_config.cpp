#include "central_config.hpp"

#include "cdc/config/reader.hpp"

#include <array>

namespace cdc::central {

CentralNodeOptions load_options(const std::string& path) {
  CentralNodeOptions o;
  config::Reader r(path);
  r.get_count("robots", o.core.robot_count, 1, 254);
  r.get_count("central_id", o.central_id, 0, 254);
  r.get_in("central_on_robot", o.central_on_robot, -1, 253);  // -1: a fixed position
  std::array<double, 3> pos{0, 0, 0};
  r.get_position("central_position", pos);
  o.central_position = Eigen::Vector3d(pos[0], pos[1], pos[2]);
  r.get_in("lease_ms", o.lease_ms, 50, 60000);
  r.get_in("hang_timeout_ms", o.hang_timeout_ms, 50, 600000);
  r.get_count("max_pending_keyframes", o.core.max_pending_keyframes, 1, 10'000'000);
  r.get_in("update_period_ms", o.update_period_ms, 1, 60000);
  r.get_in("status_period_ms", o.status_period_ms, 1, 60000);
  r.get_in("max_result_age_ms", o.max_result_age_ms, 1, 3'600'000);
  r.get_in("result_pose_rate", o.result_pose_rate, 0.0, 1e9);
  r.get_in("optimiser.max_iterations", o.core.max_iterations_per_update, 1, 10000);
  double max_time_ms = o.core.max_time_per_update_s * 1e3;
  r.get_in("optimiser.max_time_ms", max_time_ms, 0.1, 600000.0);
  o.core.max_time_per_update_s = max_time_ms * 1e-3;
  r.get_in("optimiser.window", o.core.window, 0u, 1'000'000u);
  r.get_in("optimiser.full_every", o.core.full_every, 1u, 1'000'000u);
  r.get_in("optimiser.full_growth", o.core.full_growth, 0.0, 10.0);
  r.get_in("optimiser.full_pass_iterations", o.core.full_pass_iterations, 1, 10000);
  double full_pass_ms = o.core.full_pass_time_s * 1e3;
  r.get_in("optimiser.full_pass_time_ms", full_pass_ms, 0.1, 600000.0);
  o.core.full_pass_time_s = full_pass_ms * 1e-3;
  r.get_in("optimiser.loop_robust_scale", o.core.loop_robust_scale, 0.0, 1e6);
  r.get<bool>("optimiser.loop_gnc", o.core.loop_gnc);
  r.get_in("optimiser.loop_gnc_threshold", o.core.loop_gnc_threshold, 1e-9, 1e9);
  r.get_in("optimiser.loop_gnc_median_ratio", o.core.loop_gnc_median_ratio, 1.0, 1e9);
  r.get_in("optimiser.loop_gnc_rounds", o.core.loop_gnc_rounds, 1, 1000);
  r.get<bool>("optimiser.share_loop_information", o.core.share_loop_information);
  r.get<std::string>("log_level", o.log_level);
  if (const int robots = static_cast<int>(o.core.robot_count); o.central_on_robot >= robots) {
    r.error("central_on_robot " + std::to_string(o.central_on_robot) + " is not one of the " + std::to_string(robots) +
            " robots");
  }
  r.finish();
  return o;
}

}  // namespace cdc::central
