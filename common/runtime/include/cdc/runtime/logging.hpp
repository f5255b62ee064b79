// Logging set-up shared by every service: one stderr logger named after the process.
#pragma once

#include <Eigen/Geometry>

#include <cstdint>
#include <string>

namespace cdc::runtime {

// level: trace, debug, info, warn, error. Throws std::invalid_argument for anything else.
void init_logging(const std::string& process_name, const std::string& level = "info");

// Logs a switch of the emulated radio (dds::RobotDomains' notification), the same way in every service.
void log_radio_switch(bool in_range);

// A robot's world estimate as its front-end takes it, for a log line: T_world_robot (translation in m,
// rotation vector in mrad) and the newest keyframe's position in W and in the robot's odometry frame L.
std::string world_estimate_text(const Eigen::Isometry3d& T_world_robot, uint32_t keyframe,
                                const Eigen::Isometry3d& T_world_keyframe);

}  // namespace cdc::runtime
