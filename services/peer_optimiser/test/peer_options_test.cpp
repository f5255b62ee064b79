// peer_optimiser.yaml -> PeerNodeOptions: the shipped file loads, and a bad value or an unknown key
// is named in the error.
#include "../src/peer_options.hpp"

#include "cdc/config/reader.hpp"

#include <gtest/gtest.h>

#include <unistd.h>
#include <filesystem>
#include <fstream>

namespace cdc::peer {
namespace {

using namespace std::chrono_literals;

std::string write_yaml(const std::string& text) {
  const auto p = std::filesystem::temp_directory_path() / ("cdc-peer-options-" + std::to_string(::getpid()) + ".yaml");
  std::ofstream(p) << text;
  return p.string();
}

std::string error_of(const std::string& yaml) {
  try {
    load_options(write_yaml(yaml));
  } catch (const config::ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(PeerOptions, KeysLeftOutKeepTheCoresDefaults) {
  const PeerNodeOptions o = load_options(write_yaml("robots: 3\n"));
  const PeerConfig core;
  EXPECT_EQ(o.core.separator_refresh, core.separator_refresh);
  EXPECT_EQ(o.core.separator_refresh, 30000ms);
  EXPECT_EQ(o.core.rtdos.dwell, core.rtdos.dwell);
  EXPECT_EQ(o.core.rtdos.mask, core.rtdos.mask);
  EXPECT_EQ(o.core.round_period, core.round_period);
  EXPECT_EQ(o.core.resend_grace, core.resend_grace);
  EXPECT_EQ(o.core.resend_period, core.resend_period);
}

TEST(PeerOptions, ShippedFileLoads) {
  const PeerNodeOptions o = load_options(CDC_PEER_YAML);
  EXPECT_EQ(o.core.robot_count, 3u);
  EXPECT_EQ(o.central_id, 200u);
  EXPECT_EQ(o.core.rtdos.range_m, 100.0);
  EXPECT_EQ(o.core.rtdos.dwell, 3000ms);
  EXPECT_EQ(o.core.separator_refresh, 30000ms);
  EXPECT_NEAR(o.core.fusion.rot_max, 1.0 * M_PI / 180.0, 1e-12);
  EXPECT_EQ(o.tick_ms, 50);
  EXPECT_EQ(o.status_period_ms, 250);
  EXPECT_EQ(o.radio_status_period_ms, 1000);
  EXPECT_FLOAT_EQ(o.map_cloud_resolution_m, 0.02f);
  EXPECT_EQ(o.log_level, "info");
}

TEST(PeerOptions, BadValuesAndUnknownKeysAreNamed) {
  EXPECT_NE(error_of("robots: 0\n").find("robots"), std::string::npos);
  EXPECT_NE(error_of("distributed_relaxation: 1.5\n").find("distributed_relaxation"), std::string::npos);
  EXPECT_NE(error_of("range_m: 10\nhysteresis_m: 10\n").find("hysteresis_m must be smaller than range_m"),
            std::string::npos);
  EXPECT_NE(error_of("tick_msec: 5\n").find("tick_msec"), std::string::npos);
  EXPECT_EQ(error_of("central_id: 250\ntick_ms: 20\n"), "");
  EXPECT_NE(error_of("map_cloud_resolution_m: 0\n").find("map_cloud_resolution_m"), std::string::npos);
}

// The flap damping keys have finite ranges like every other number in the file.
TEST(PeerOptions, FlapDampingKeysAreRanged) {
  EXPECT_NE(error_of("flap_window_ms: -1\n").find("flap_window_ms"), std::string::npos);
  EXPECT_NE(error_of("flap_window_ms: 3600001\n").find("flap_window_ms"), std::string::npos);
  EXPECT_NE(error_of("max_dwell_factor: 0\n").find("max_dwell_factor"), std::string::npos);
  EXPECT_NE(error_of("max_dwell_factor: 65\n").find("max_dwell_factor"), std::string::npos);
  const PeerNodeOptions o = load_options(write_yaml("flap_window_ms: 0\nmax_dwell_factor: 64\n"));
  EXPECT_EQ(o.core.rtdos.flap_window, 0ms);
  EXPECT_EQ(o.core.rtdos.max_dwell_factor, 64u);
}

}  // namespace
}  // namespace cdc::peer
