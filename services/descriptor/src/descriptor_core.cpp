#include "cdc/descriptor/descriptor_core.hpp"

namespace cdc::descriptor {

DescriptorCore::DescriptorCore(const lidar::ScanContextParams& params, uint32_t max_per_sync)
    : params_(params), max_per_sync_(max_per_sync) {}

const DescriptorRecord* DescriptorCore::describe(const KeyframeCloud& k) {
  if (!described_.insert({k.incarnation, k.keyframe_id}).second) {
    ++counters_.repeated;
    return nullptr;
  }
  if (k.incarnation != incarnation_) {
    kept_.clear();
    incarnation_ = k.incarnation;
  }
  DescriptorRecord& r = kept_[k.keyframe_id];
  r.robot = k.robot;
  r.incarnation = k.incarnation;
  r.keyframe_id = k.keyframe_id;
  r.stamp_ns = k.stamp_ns;
  r.pose_hint = k.T_odom_keyframe;
  r.descriptor = lidar::quantize(lidar::make_scan_context(k.points, params_));
  ++counters_.described;
  return &r;
}

std::vector<const DescriptorRecord*> DescriptorCore::resend(uint32_t first, uint32_t last) const {
  std::vector<const DescriptorRecord*> out;
  for (auto it = kept_.lower_bound(first); it != kept_.end() && it->first <= last && out.size() < max_per_sync_; ++it) {
    out.push_back(&it->second);
  }
  return out;
}

}  // namespace cdc::descriptor
