#include "cdc/loop_closure/loop_core.hpp"

#include <utility>

namespace cdc::loops {

void LoopEvents::append(LoopEvents&& o) {
  loops.insert(loops.end(), o.loops.begin(), o.loops.end());
  requests.insert(requests.end(), o.requests.begin(), o.requests.end());
  verifications.insert(verifications.end(), o.verifications.begin(), o.verifications.end());
}

lidar::ScanContext wire_form(const lidar::ScanContext& sc) { return lidar::dequantize(lidar::quantize(sc)); }

LoopCore::LoopCore(const LoopParams& params, std::optional<uint32_t> query_robot)
    : p_(params),
      retrieval_(params, query_robot),
      clouds_(params),
      requests_(params),
      verifier_(params),
      pcm_(params) {}

LoopEvents LoopCore::add_keyframe_data(KeyframeIn kf, Nanos now) {
  const KeyframeId me{kf.robot, kf.id};
  if (clouds_.is_local(me)) {
    return {};
  }
  pcm_.add_keyframe_odometry(kf.robot, kf.id, kf.T_prev, kf.information);
  retrieval_.add_odometry(kf.robot, kf.id, kf.T_prev);
  clouds_.add_local(me, kf.cloud, kf.T_odom.linear().transpose() * Eigen::Vector3d::UnitZ());
  retrieval_.add_views(me, lane_views(kf.cloud));
  std::optional<DescriptorIn> waiting = retrieval_.take_deferred(me);
  return waiting ? add_descriptor(std::move(*waiting), now) : LoopEvents{};
}

std::vector<ShiftedView> LoopCore::lane_views(const std::vector<Eigen::Vector3f>& cloud) const {
  std::vector<ShiftedView> views;
  for (double y : p_.lane_views_m) {
    const Eigen::Vector3d sensor(0, y, 0);
    views.push_back({wire_form(lidar::make_scan_context(cloud, p_.scan_context, sensor.cast<float>())), sensor});
  }
  return views;
}

LoopEvents LoopCore::add_descriptor(DescriptorIn d, Nanos now) {
  const KeyframeId me{d.robot, d.id};
  if (retrieval_.waits_for_keyframe(d, clouds_.is_local(me))) {
    retrieval_.defer(std::move(d));
    return {};
  }
  if (!retrieval_.first_description(me)) {
    return {};
  }
  if (retrieval_.is_peer(d.robot)) {
    requests_.add_pose_hint(me, d.pose_hint);
  }
  pcm_.add_pose_hint(d.robot, d.id, d.pose_hint);
  LoopEvents out;
  for (const VerificationJob& job : retrieval_.search(std::move(d), clouds_.is_local(me))) {
    route(job, now, out);
  }
  return out;
}

void LoopCore::route(const VerificationJob& job, Nanos now, LoopEvents& out) {
  if (clouds_.holds(job.candidate)) {
    if (first_try(job)) out.append(verify(job));
    return;
  }
  const CloudRequests::Reaimed n = requests_.reaim(job, [&](const KeyframeId& id) { return clouds_.holds(id); });
  if (n.job) {
    route_to_neighbour(*n.job, now, out);
    return;
  }
  if (n.too_far) {
    ++routing_.reaim_too_far;
    return;
  }
  if (tried_.count({job.query, job.candidate}) != 0) {
    return;  // already waiting for this cloud
  }
  if (!requests_.reserve(job.candidate)) {
    return;
  }
  first_try(job);
  requests_.wait_for(job, now, out.requests);
}

void LoopCore::route_to_neighbour(const VerificationJob& neighbour, Nanos now, LoopEvents& out) {
  // Several candidates of one query can share a neighbour: that pair is verified once.
  if (!first_try(neighbour)) return;
  ++routing_.verified_with_neighbour;
  if (clouds_.holds(neighbour.candidate)) {
    out.append(verify(neighbour));
  } else {
    requests_.wait_for(neighbour, now, out.requests);
  }
}

LoopEvents LoopCore::verify(const VerificationJob& job) {
  LoopEvents out;
  std::optional<Verifier::Outcome> v = verifier_.verify(job, clouds_);
  if (!v) {
    return out;
  }
  out.verifications.push_back(v->record);
  if (v->loop) {
    out.loops = pcm_.add_loop(*v->loop);
  }
  return out;
}

LoopEvents LoopCore::on_cloud(uint32_t robot, uint32_t id, std::vector<Eigen::Vector3f> cloud, Nanos) {
  LoopEvents out;
  const KeyframeId key{robot, id};
  const std::optional<std::vector<VerificationJob>> jobs = requests_.answered(key);
  if (!jobs) {
    return out;
  }
  clouds_.add_received(key, cloud);
  for (const VerificationJob& j : *jobs) {
    out.append(verify(j));
  }
  return out;
}

ReplyUse LoopCore::reply_use(uint32_t robot, uint32_t id, bool found) const {
  if (!is_wanted(robot, id)) {
    return cloud(robot, id) != nullptr ? ReplyUse::kDuplicate : ReplyUse::kUnrequested;
  }
  return found ? ReplyUse::kCloud : ReplyUse::kNotHeld;
}

LoopEvents LoopCore::tick(Nanos now) {
  LoopEvents out;
  out.requests = requests_.tick(now);
  return out;
}

std::vector<LoopOut> LoopCore::add_keyframe(KeyframeIn kf) {
  DescriptorIn d;
  d.robot = kf.robot;
  d.id = kf.id;
  d.context = wire_form(lidar::make_scan_context(kf.cloud, p_.scan_context));
  add_keyframe_data(std::move(kf), Nanos(0));
  return add_descriptor(std::move(d), Nanos(0)).loops;
}

LoopStats LoopCore::stats() const {
  LoopStats s;
  static_cast<RetrievalStats&>(s) = retrieval_.stats();
  static_cast<RequestStats&>(s) = requests_.stats();
  static_cast<CloudStoreStats&>(s) = clouds_.stats();
  static_cast<VerificationStats&>(s) = verifier_.stats();
  static_cast<PcmStats&>(s) = pcm_.stats();
  static_cast<RoutingStats&>(s) = routing_;
  return s;
}

}  // namespace cdc::loops
