// Recovery of a registration the prediction led astray (RecoveryParams in frontend_types.hpp): how
// well a registration fits the map, whether it is poor against the recent sweeps' fits, and the
// search for a better one from other guesses (coarse to fine from the prediction, from the last
// pose, from a global registration onto the previous sweep).
#pragma once

#include "cdc/frontend/deskewing.hpp"
#include "cdc/frontend/frontend_types.hpp"
#include "cdc/odometry/global_registration.hpp"
#include "cdc/odometry/registration.hpp"
#include "cdc/odometry/voxel_map.hpp"

#include <Eigen/Geometry>

#include <deque>
#include <functional>
#include <optional>
#include <vector>

namespace cdc::frontend {

// Whether a converged registration is a step the robot can have made: within max_gate_m and
// max_jump_rad of the prediction. Beyond, it has slid into a wrong minimum (seen with miscalibrated
// LiDARs: 4.8 m down in one sweep) and the prediction is kept instead.
bool plausible_registration(const Eigen::Isometry3d& prediction, const Eigen::Isometry3d& registered,
                            const FrontendParams& p);

// A registration of a sweep, how well it fits the map and the guess it started from.
struct Candidate {
  odometry::RegistrationResult reg;
  odometry::FitQuality fit;
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
};

// What registering one sweep works with: the map, the registration's parameters (the adaptive
// gate), the previous sweep's registered pose and, when the sweep is deskewed again with the motion
// a registration implies, how (the sweep deskewed for a registered pose; empty: never again).
struct RegistrationContext {
  const odometry::VoxelMap& map;
  odometry::RegistrationSettings params;
  Eigen::Isometry3d T_last = Eigen::Isometry3d::Identity();
  std::function<Sweep(const Eigen::Isometry3d& T_map_sensor)> redeskew;
};

class RegistrationRecovery {
 public:
  explicit RegistrationRecovery(const FrontendParams& params);

  odometry::FitQuality fit_of(const Sweep& sweep, const odometry::VoxelMap& map,
                              const odometry::RegistrationResult& reg) const;
  // The median fit of the recent registrations; 0 while there are fewer than recovery.min_history.
  double recent_fit() const;
  // Whether a registration from `guess` needs recovery.
  bool poor(const Eigen::Isometry3d& guess, const Candidate& c) const;

  struct Outcome {
    bool recovered = false;  // `c` replaced by a registration that fits clearly better
    bool global = false;     // ... which started from the global registration
  };
  // Registers again from other guesses; replaces `c` (and `sweep`, when deskewed again) with a
  // plausible registration that fits clearly better, if one is found.
  Outcome recover(const Eigen::Isometry3d& guess, const RegistrationContext& ctx, Sweep& sweep, Candidate& c);

  // The fit of a registration taken.
  void remember_fit(double inlier_fraction);
  // The sweep just registered (sensor frame) for the next one's global registration, with its
  // features if recovery made them.
  void remember_sweep(std::vector<Eigen::Vector3d> cloud);

 private:
  // The state of one search: the fit to beat, the fit that ends it, whether `c` was replaced.
  struct Search {
    double best = -1.0, good = 2.0;
    bool replaced = false;
  };
  // One attempt from `start`: true when it fits well enough to end the search.
  bool attempt(const Eigen::Isometry3d& start, const RegistrationContext& ctx, Search& search, Sweep& sweep,
               Candidate& c) const;
  // Registration from `start` through the wide gates down to the adaptive one.
  odometry::RegistrationResult coarse_to_fine(const Sweep& sweep, const RegistrationContext& ctx,
                                              const Eigen::Isometry3d& start) const;
  // The global registration of `sweep` onto the previous sweep, put on the previous pose.
  std::optional<Eigen::Isometry3d> global_guess(const Sweep& sweep, const Eigen::Isometry3d& T_last);

  FrontendParams p_;
  std::deque<double> recent_fits_;  // fit (inlier fraction) of the last accepted registrations
  // The previous sweep (sensor frame, as registered) and its features once made; the features of
  // the sweep being processed, if recovery made them.
  std::vector<Eigen::Vector3d> prev_cloud_;
  std::optional<odometry::FeatureCloud> prev_features_, current_features_;
};

}  // namespace cdc::frontend
