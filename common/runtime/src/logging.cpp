#include "cdc/runtime/logging.hpp"

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

}  // namespace cdc::runtime
