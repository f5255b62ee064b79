// Scan-to-map registration of a sweep against the voxel map (common/odometry): from the predicted
// pose with the adaptive gate; refined after deskewing the sweep again with the registered motion
// (FrontendParams::redeskew); recovered when poor (registration_recovery.hpp); rejected when it has
// slid implausibly far from the guess it started from, the prediction then standing for it.
#pragma once

#include "cdc/frontend/deskewing.hpp"
#include "cdc/frontend/frontend_types.hpp"
#include "cdc/frontend/registration_recovery.hpp"
#include "cdc/odometry/registration.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

namespace cdc::frontend {

class ScanToMapRegistration {
 public:
  explicit ScanToMapRegistration(const FrontendParams& params);

  // The sweep registered from `guess`.
  Candidate register_from(const Sweep& sweep, const RegistrationContext& ctx, const Eigen::Isometry3d& guess) const;

  struct Result {
    odometry::RegistrationResult reg;  // not converged: failed, or rejected as implausible
    odometry::FitQuality fit;
    bool recovered = false;  // taken from recovery
  };
  // The registration `c` from `guess` completed: refined on the sweep deskewed again (when
  // ctx.redeskew is set; `sweep` is replaced), recovered if poor, and checked (counted in stats).
  Result complete(const Eigen::Isometry3d& guess, const RegistrationContext& ctx, Sweep& sweep, Candidate& c,
                  FrontendStats& stats);

  RegistrationRecovery& recovery() noexcept { return recovery_; }
  const RegistrationRecovery& recovery() const noexcept { return recovery_; }

 private:
  FrontendParams p_;
  RegistrationRecovery recovery_;
};

}  // namespace cdc::frontend
