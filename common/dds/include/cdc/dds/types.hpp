// The IDL types known to the DDS layer: TypeSupport<T> gives each generated struct its descriptor.
#pragma once

#include <dds/dds.h>

#include "cdc/sensor.h"
#include "cdc/sim.h"
#include "cdc/slam.h"
#include "cdc/types.h"

namespace cdc::dds {

template <class T>
struct TypeSupport;  // defined below for every topic type; a missing one is a compile error

#define CDC_DDS_TYPE(T)                                                     \
  template <>                                                               \
  struct TypeSupport<T> {                                                   \
    static const dds_topic_descriptor_t* descriptor() { return &T##_desc; } \
    static constexpr const char* kName = #T;                                \
  }

CDC_DDS_TYPE(cdc_msg_LidarScan);
CDC_DDS_TYPE(cdc_msg_ImuBatch);
CDC_DDS_TYPE(cdc_msg_Odometry);
CDC_DDS_TYPE(cdc_msg_Keyframe);
CDC_DDS_TYPE(cdc_msg_KeyframeCloud);
CDC_DDS_TYPE(cdc_msg_Descriptor);
CDC_DDS_TYPE(cdc_msg_DescriptorSync);
CDC_DDS_TYPE(cdc_msg_LoopClosure);
CDC_DDS_TYPE(cdc_msg_CloudRequest);
CDC_DDS_TYPE(cdc_msg_CloudReply);
CDC_DDS_TYPE(cdc_msg_OptimizedPoses);
CDC_DDS_TYPE(cdc_msg_SeparatorPoses);
CDC_DDS_TYPE(cdc_msg_WorldTransform);
CDC_DDS_TYPE(cdc_msg_KeyframeSequence);
CDC_DDS_TYPE(cdc_msg_ModeState);
CDC_DDS_TYPE(cdc_msg_RobotStatus);
CDC_DDS_TYPE(cdc_msg_Acknowledgement);
CDC_DDS_TYPE(cdc_msg_GroundTruth);
CDC_DDS_TYPE(cdc_msg_RadioState);
CDC_DDS_TYPE(cdc_msg_ConsumerProgress);

#undef CDC_DDS_TYPE

// Points a generated sequence at caller-owned storage without copying. dds_write serialises
// synchronously, so the storage only has to outlive the write call.
template <class Seq, class Vec>
void borrow(Seq& seq, Vec& storage) {
  seq._buffer = storage.data();
  seq._length = static_cast<uint32_t>(storage.size());
  seq._maximum = static_cast<uint32_t>(storage.size());
  seq._release = false;
}

}  // namespace cdc::dds
