// Logging set-up shared by every service: one stderr logger named after the process.
#pragma once

#include <string>

namespace cdc::runtime {

// level: trace, debug, info, warn, error. Throws std::invalid_argument for anything else.
void init_logging(const std::string& process_name, const std::string& level = "info");

// Logs a switch of the emulated radio (dds::RobotDomains' notification), the same way in every service.
void log_radio_switch(bool in_range);

}  // namespace cdc::runtime
