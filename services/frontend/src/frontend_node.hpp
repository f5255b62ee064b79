// DDS glue of the front-end: the robot's LiDAR sweeps, IMU batches and the back-end's
// corrections in; odometry at scan rate, keyframes and lock-step progress out.
#pragma once

#include "frontend_config.hpp"

namespace cdc::frontend {

int run_frontend(const FrontendNodeOptions& options);

}  // namespace cdc::frontend
