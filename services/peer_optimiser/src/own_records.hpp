// What the node keeps beside the core for re-sending: the clouds of the robot's own keyframes (the
// core owns the keyframes themselves and has no use for their points) and its own loop closures as
// they came in.
#pragma once

#include "cdc/dds/types.hpp"

#include <cstddef>
#include <cstdint>
#include <map>
#include <vector>

namespace cdc::peer {

class OwnRecords {
 public:
  // Copies the keyframe's cloud (a reader lends its samples only while they are handled). Only for
  // a keyframe the core has accepted: a cloud already held under its id is kept, never replaced.
  void keep_cloud(const cdc_msg_Keyframe& m);
  void keep(const cdc_msg_LoopClosure& m);

  // The cloud of keyframe `id`, to lend to a re-sent message; nullptr when none is held.
  std::vector<cdc_msg_PointXYZI>* cloud(uint32_t id);
  const cdc_msg_LoopClosure* loop(uint32_t seq) const;
  size_t clouds() const noexcept { return clouds_.size(); }

 private:
  std::map<uint32_t, std::vector<cdc_msg_PointXYZI>> clouds_;
  std::map<uint32_t, cdc_msg_LoopClosure> loops_;
};

}  // namespace cdc::peer
