#include "cdc/loop_closure/verifier.hpp"

#include "cdc/graph/pose_graph.hpp"

namespace cdc::loops {

std::optional<Verifier::Outcome> Verifier::verify(const VerificationJob& job, CloudStore& clouds) {
  if (!clouds.holds(job.query) || !clouds.holds(job.candidate)) {
    return std::nullopt;
  }
  // The query's cloud is made ready last, so that it stays ready longest: a query's candidates are
  // verified in a burst.
  const auto target = clouds.prepared(job.candidate);
  const auto source = clouds.prepared(job.query);
  const odometry::RegistrationResult r = odometry::register_gicp(*source, *target, job.guess, p_.registration);
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
                            job.guess.translation().norm(),
                            (job.guess.inverse() * r.T_target_source).translation().norm()};
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
