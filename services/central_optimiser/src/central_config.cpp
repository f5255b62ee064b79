#include "central_config.hpp"

#include "cdc/config/reader.hpp"

namespace cdc::central {

CentralNodeOptions load_options(const std::string& path) {
  CentralNodeOptions o;
  config::Reader r(path);
  auto positive = [](const int& v) { return v > 0; };
  int robots = static_cast<int>(o.core.robot_count);
  r.get<int>(
      "robots", robots, [](const int& v) { return v >= 1 && v <= 254; }, "1..254");
  o.core.robot_count = static_cast<uint32_t>(robots);
  int central_id = static_cast<int>(o.central_id);
  r.get<int>(
      "central_id", central_id, [](const int& v) { return v >= 0 && v <= 254; }, "0..254");
  o.central_id = static_cast<uint32_t>(central_id);
  r.get<int>(
      "central_on_robot", o.central_on_robot, [](const int& v) { return v >= -1 && v <= 254; }, "-1 or a robot id");
  std::vector<double> pos{0, 0, 0};
  r.get<std::vector<double>>(
      "central_position", pos, [](const std::vector<double>& v) { return v.size() == 3; }, "[x, y, z]");
  o.central_position = Eigen::Vector3d(pos[0], pos[1], pos[2]);
  r.get<int>(
      "lease_ms", o.lease_ms, [](const int& v) { return v >= 50 && v <= 60000; }, "50..60000");
  int max_pending = static_cast<int>(o.core.max_pending_keyframes);
  r.get<int>(
      "max_pending_keyframes", max_pending, [](const int& v) { return v >= 1 && v <= 10'000'000; }, "1..10000000");
  o.core.max_pending_keyframes = static_cast<size_t>(max_pending);
  r.get<int>("update_period_ms", o.update_period_ms, positive, "> 0");
  r.get<int>("status_period_ms", o.status_period_ms, positive, "> 0");
  r.get<int>("max_result_age_ms", o.max_result_age_ms, positive, "> 0");
  r.get<int>("optimiser.max_iterations", o.core.max_iterations_per_update, positive, "> 0");
  double max_time_ms = o.core.max_time_per_update_s * 1e3;
  r.get<double>(
      "optimiser.max_time_ms", max_time_ms, [](const double& v) { return v > 0; }, "> 0");
  o.core.max_time_per_update_s = max_time_ms * 1e-3;
  r.get<uint32_t>("optimiser.window", o.core.window);
  r.get<uint32_t>(
      "optimiser.full_every", o.core.full_every, [](const uint32_t& v) { return v >= 1; }, ">= 1");
  r.get<int>("optimiser.full_pass_iterations", o.core.full_pass_iterations, positive, "> 0");
  double full_pass_ms = o.core.full_pass_time_s * 1e3;
  r.get<double>(
      "optimiser.full_pass_time_ms", full_pass_ms, [](const double& v) { return v > 0; }, "> 0");
  o.core.full_pass_time_s = full_pass_ms * 1e-3;
  r.get<double>(
      "optimiser.loop_robust_scale", o.core.loop_robust_scale, [](const double& v) { return v >= 0; }, ">= 0");
  r.get<bool>("optimiser.share_loop_information", o.core.share_loop_information);
  r.get<std::string>("log_level", o.log_level);
  if (o.central_on_robot >= robots) {
    r.error("central_on_robot " + std::to_string(o.central_on_robot) + " is not one of the " + std::to_string(robots) +
            " robots");
  }
  r.finish();
  return o;
}

}  // namespace cdc::central
