#include "cdc/runtime/logging.hpp"

#include <spdlog/fmt/fmt.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>

#include <stdexcept>

namespace cdc::runtime {

void init_logging(const std::string& process_name, const std::string& level) {
  const auto lvl = spdlog::level::from_str(level);
  if (lvl == spdlog::level::off && level != "off") {
    throw std::invalid_argument("unknown log level '" + level + "' (trace, debug, info, warn, error)");
  }
  auto logger = spdlog::stderr_color_mt(process_name);
  logger->set_pattern("%H:%M:%S.%e %n %^%l%$ %v");
  logger->set_level(lvl);
  spdlog::set_default_logger(logger);
}

void log_radio_switch(bool in_range) {
  spdlog::info("emulated radio: {}", in_range ? "back in range" : "out of range (deaf and mute on the SLAM domain)");
}

std::string world_estimate_text(const Eigen::Isometry3d& T_world_robot, uint32_t keyframe,
                                const Eigen::Isometry3d& T_world_keyframe) {
  const Eigen::Vector3d t = T_world_robot.translation();
  const Eigen::AngleAxisd r(T_world_robot.linear());
  const Eigen::Vector3d rv = r.angle() * r.axis() * 1e3;
  const Eigen::Vector3d w = T_world_keyframe.translation();
  const Eigen::Vector3d l = (T_world_robot.inverse() * T_world_keyframe).translation();
  return fmt::format(
      "T_world_robot ({:.3f}, {:.3f}, {:.3f}) m ({:.3f}, {:.3f}, {:.3f}) mrad; newest keyframe {} at ({:.3f}, {:.3f}, "
      "{:.3f}) in W, ({:.3f}, {:.3f}, {:.3f}) in L",
      t.x(), t.y(), t.z(), rv.x(), rv.y(), rv.z(), keyframe, w.x(), w.y(), w.z(), l.x(), l.y(), l.z());
}

}  // namespace cdc::runtime
