// The central optimiser's configuration (services/central_optimiser/config/central_optimiser.yaml).
#pragma once

#include "cdc/central_optimiser/central_core.hpp"

#include <Eigen/Core>

#include <cstdint>
#include <string>

namespace cdc::central {

// The domain and the statistics file are the shared options' (runtime::ServiceOptions).
struct CentralNodeOptions {
  CentralConfig core;
  uint32_t central_id = 200;  // node id of the central in status messages
  int central_on_robot = 0;   // the central rides on this robot; -1: fixed position
  Eigen::Vector3d central_position = Eigen::Vector3d::Zero();
  int lease_ms = 1000;           // liveliness lease of the results writer
  int hang_timeout_ms = 10000;   // liveliness lapses when the work loop makes no progress this long
  int update_period_ms = 100;    // least time between optimisations
  int max_result_age_ms = 2000;  // results of an unsettled graph are held back at most this long
  int status_period_ms = 250;
  double result_pose_rate = 3000;  // poses per second per robot in results (0: every update's, at once)
  std::string graph_out;           // write the final graph (g2o) here at shutdown
  std::string log_level = "info";
};

// Loads a YAML configuration file over the defaults; throws config::ConfigError listing problems.
CentralNodeOptions load_options(const std::string& path);

}  // namespace cdc::central
