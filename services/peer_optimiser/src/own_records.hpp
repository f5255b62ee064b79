// What the node keeps beside the core for forwarding and re-sending: the clouds of the robot's own
// keyframes, packed for the radio (the core owns the keyframes themselves and has no use for their
// points), and its own loop closures as they came in.
#pragma once

#include "cdc/dds/compact.hpp"
#include "cdc/dds/types.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

namespace cdc::peer {

class OwnRecords {
 public:
  // Packs the keyframe's cloud (x, y, z to a grid of resolution_m [m]; a reader lends its samples only
  // while they are handled) and returns what is kept under its id. Only for a keyframe the core has
  // accepted: a cloud already held under its id is kept, never replaced.
  dds::compact::PackedCloud& keep_cloud(const cdc_msg_Keyframe& m, float resolution_m);
  void keep(const cdc_msg_LoopClosure& m);

  // The packed cloud of keyframe `id`, to lend to a re-sent message; nullptr when none is held.
  dds::compact::PackedCloud* cloud(uint32_t id);
  const cdc_msg_LoopClosure* loop(uint32_t seq) const;
  size_t clouds() const noexcept { return clouds_.size(); }

 private:
  std::map<uint32_t, dds::compact::PackedCloud> clouds_;
  std::map<uint32_t, cdc_msg_LoopClosure> loops_;
  std::vector<Eigen::Vector3f> points_;  // scratch for packing
};

}  // namespace cdc::peer
