// Verification: a candidate's geometry checked by registering the query keyframe's cloud to the
// candidate's (GICP from the job's guess, moved in height to put the two grounds level when they
// disagree with it by more than ground_guess_min_m). A registration that converges with a fitness within
// max_fitness and an overlap of min_overlap or more makes a loop, whose information is the
// registration's x loop_information_scale with its tilt levelled in the query keyframe's frame
// (tilt_information_scale). Synchronous, no I/O.
#pragma once

#include "cdc/loop_closure/cloud_store.hpp"
#include "cdc/loop_closure/loop_types.hpp"

#include <cstdint>
#include <optional>

namespace cdc::loops {

struct VerificationStats {
  uint64_t verified = 0, verification_failed = 0;
  // Why verifications failed (each failure counts under its first reason).
  uint64_t failed_not_converged = 0, failed_fitness = 0, failed_overlap = 0;
};

class Verifier {
 public:
  explicit Verifier(const LoopParams& params) : p_(params) {}

  struct Outcome {
    Verification record;
    std::optional<LoopOut> loop;  // when it passed: robot_a / keyframe_a the candidate, b the query
  };
  // The job registered with the clouds held in `clouds`; nullopt when either is not held there.
  std::optional<Outcome> verify(const VerificationJob& job, CloudStore& clouds);

  const VerificationStats& stats() const noexcept { return stats_; }

 private:
  // The job's guess, moved in height to put the two clouds' grounds level when it leaves them more
  // than ground_guess_min_m apart.
  Eigen::Isometry3d level_grounds(const VerificationJob& job, const CloudStore& clouds) const;
  // Counts the failure under its first reason; true when the registration passed.
  bool passes(const odometry::RegistrationResult& r);

  LoopParams p_;
  VerificationStats stats_;
};

}  // namespace cdc::loops
