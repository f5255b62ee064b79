// The descriptor service's work without DDS: a robot's keyframe clouds in, their quantised Scan Context
// descriptors out, each (incarnation, keyframe) once; the current incarnation's descriptors kept to answer
// a peer that asks for a range it missed.
#pragma once

#include "cdc/lidar/scan_context.hpp"

#include <Eigen/Geometry>

#include <cstdint>
#include <map>
#include <set>
#include <utility>
#include <vector>

namespace cdc::descriptor {

struct KeyframeCloud {
  uint32_t robot = 0, incarnation = 0, keyframe_id = 0;
  int64_t stamp_ns = 0;
  Eigen::Isometry3d T_odom_keyframe = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Vector3f> points;  // keyframe frame
};

struct DescriptorRecord {
  uint32_t robot = 0, incarnation = 0, keyframe_id = 0;
  int64_t stamp_ns = 0;
  Eigen::Isometry3d pose_hint = Eigen::Isometry3d::Identity();  // the keyframe's odometry pose
  lidar::QuantizedScanContext descriptor;
};

struct DescriptorCounters {
  uint64_t described = 0;
  uint64_t repeated = 0;  // keyframes described before (re-sent to a central that lacked them)
};

class DescriptorCore {
 public:
  // max_per_sync: at most this many descriptors answer one request (the requester asks again for more).
  DescriptorCore(const lidar::ScanContextParams& params, uint32_t max_per_sync);

  // The keyframe's descriptor, or nullptr when this (incarnation, keyframe) was described before.
  // A new incarnation (a restarted front-end numbers its keyframes afresh) replaces the kept ones.
  const DescriptorRecord* describe(const KeyframeCloud& keyframe);

  // The current incarnation's descriptors with ids in [first, last], in id order, at most max_per_sync.
  std::vector<const DescriptorRecord*> resend(uint32_t first, uint32_t last) const;

  const lidar::ScanContextParams& params() const noexcept { return params_; }
  const DescriptorCounters& counters() const noexcept { return counters_; }

 private:
  lidar::ScanContextParams params_;
  uint32_t max_per_sync_;
  std::set<std::pair<uint32_t, uint32_t>> described_;  // (incarnation, keyframe id)
  uint32_t incarnation_ = 0;
  std::map<uint32_t, DescriptorRecord> kept_;  // this incarnation's, by keyframe id
  DescriptorCounters counters_;
};

}  // namespace cdc::descriptor
