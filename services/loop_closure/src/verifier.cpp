#include "cdc/loop_closure/verifier.hpp"

#include "cdc/graph/pose_graph.hpp"

#include <cmath>

namespace cdc::loops {

std::optional<Verifier::Outcome> Verifier::verify(const VerificationJob& job, CloudStore& clouds) {
  if (!clouds.holds(job.query) || !clouds.holds(job.candidate)) {
    return std::nullopt;
  }
  // The query's cloud is made ready last, so that it stays ready longest: a query's candidates are
  // verified in a burst.
  const auto target = clouds.prepared(job.candidate);
  const auto source = clouds.prepared(job.query);
  const Eigen::Isometry3d guess = level_grounds(job, clouds);
  const odometry::RegistrationResult r = odometry::register_gicp(*source, *target, guess, p_.registration);
  const auto [robot_a, kf_a] = job.candidate;
  const auto [robot_b, kf_b] = job.query;
  Outcome out;
  out.record = Verification{robot_b,
                            kf_b,
                            robot_a,
                            kf_a,
                            r.converged,
                            false,
                            r.fitness,
                            r.overlap,
                            guess.translation().norm(),
                            (guess.inverse() * r.T_target_source).translation().norm()};
  if (!passes(r)) {
    return out;
  }
  out.record.passed = true;
  // The residual's rotation is taken in the query keyframe's frame (b): level it there.
  const graph::Matrix6d information = graph::level_information(p_.loop_information_scale * r.information,
                                                               clouds.up(job.query), p_.tilt_information_scale);
  out.loop = LoopOut{robot_a, kf_a, robot_b, kf_b, r.T_target_source, information, r.fitness, false};
  return out;
}

Eigen::Isometry3d Verifier::level_grounds(const VerificationJob& job, const CloudStore& clouds) const {
  const std::optional<double> ground_candidate = clouds.ground(job.candidate), ground_query = clouds.ground(job.query);
  if (!ground_candidate || !ground_query) return job.guess;
  // A query ground point at height g_q (query frame) lands at about g_q + up . t in the candidate's
  // frame (both frames nearly level): t's height that meets the candidate's ground is g_c - g_q.
  const Eigen::Vector3d up = clouds.up(job.candidate);
  const double off = (*ground_candidate - *ground_query) - up.dot(job.guess.translation());
  if (std::abs(off) <= p_.ground_guess_min_m) return job.guess;
  Eigen::Isometry3d guess = job.guess;
  guess.translation() += off * up;
  return guess;
}

bool Verifier::passes(const odometry::RegistrationResult& r) {
  ++stats_.verified;
  if (r.converged && r.fitness <= p_.max_fitness && r.overlap >= p_.min_overlap) {
    return true;
  }
  ++stats_.verification_failed;
  ++(!r.converged                 ? stats_.failed_not_converged
     : r.fitness > p_.max_fitness ? stats_.failed_fitness
                                  : stats_.failed_overlap);
  return false;
}

}  // namespace cdc::loops
