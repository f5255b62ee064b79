// velodyne.yaml -> VelodyneDriverConfig.
#include "cdc/config/reader.hpp"
#include "cdc/velodyne_driver/velodyne_driver_core.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>

namespace cdc::velodyne_driver {

std::optional<io::VelodyneModel> parse_model(std::string_view name) {
  std::string lower(name);
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (lower == "auto") return std::nullopt;
  return io::velodyne_model_from_string(name);
}

std::optional<io::VelodyneReturnMode> parse_return_mode(std::string_view name) {
  if (name == "auto") return std::nullopt;
  if (name == "strongest") return io::VelodyneReturnMode::kStrongest;
  if (name == "last") return io::VelodyneReturnMode::kLast;
  if (name == "dual") return io::VelodyneReturnMode::kDual;
  throw std::invalid_argument("return mode '" + std::string(name) + "': expected auto, strongest, last or dual");
}

VelodyneDriverConfig load_driver_config(const std::string& path) {
  VelodyneDriverConfig c;
  config::Reader r(path);
  std::string model = c.decoder.model ? std::string(io::to_string(*c.decoder.model)) : "auto", return_mode = "auto",
              calibration;
  const auto model_ok = [](const std::string& v) {
    try {
      parse_model(v);
      return true;
    } catch (const std::invalid_argument&) {
      return false;
    }
  };
  r.get<std::string>("sensor.model", model, model_ok, "auto, VLP16, VLP32C, HDL32E, HDL64E (S2), HDL64E_S3 or VLS128");
  r.get<std::string>("sensor.calibration", calibration);
  r.get<std::string>(
      "sensor.return_mode", return_mode,
      [](const std::string& v) { return v == "auto" || v == "strongest" || v == "last" || v == "dual"; },
      "auto, strongest, last or dual");
  r.get<double>(
      "sensor.rpm", c.decoder.rpm, [](const double& v) { return v >= 60 && v <= 1500; }, "60..1500");
  r.get<double>(
      "sweep.scan_phase_deg", c.scan_phase_deg, [](const double& v) { return v >= 0 && v <= 360; }, "0..360");
  double max_gap_ms = 50;
  r.get<double>(
      "sweep.max_gap_ms", max_gap_ms, [](const double& v) { return v > 0 && v <= 10000; }, "(0, 10000]");
  c.max_gap = std::chrono::nanoseconds(static_cast<int64_t>(max_gap_ms * 1e6));
  r.get_in("filter.min_range_m", c.decoder.min_range, 0.0, 1000.0);
  r.get_in("filter.max_range_m", c.decoder.max_range, 0.1, 1000.0);
  r.get<double>(
      "filter.sector_min_deg", c.decoder.sector_min_deg, [](const double& v) { return v >= 0 && v <= 360; }, "0..360");
  r.get<double>(
      "filter.sector_max_deg", c.decoder.sector_max_deg, [](const double& v) { return v >= 0 && v <= 360; }, "0..360");
  int port = c.port;
  r.get<int>(
      "udp.port", port, [](const int& v) { return v >= 1 && v <= 65535; }, "1..65535");
  c.port = static_cast<uint16_t>(port);
  r.get_in("udp.receive_buffer_bytes", c.receive_buffer_bytes, 65536, 1 << 30);
  r.get<std::string>("log_level", c.log_level);
  if (c.decoder.min_range >= c.decoder.max_range) r.error("filter.min_range_m must be below filter.max_range_m");
  r.finish();
  c.decoder.model = parse_model(model);
  c.decoder.return_mode = parse_return_mode(return_mode);
  if (!calibration.empty()) {
    c.calibration = calibration;
    if (c.calibration.is_relative() && !path.empty())
      c.calibration = std::filesystem::path(path).parent_path() / c.calibration;
  }
  return c;
}

}  // namespace cdc::velodyne_driver
