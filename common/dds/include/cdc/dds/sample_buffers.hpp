// Deserialised samples a Reader hands out, and the take that fills them. The reader takes each
// sample in its serialised form (dds_takecdr), so the payload size it counts comes with the data
// instead of from serialising the sample a second time, and deserialises it once into these
// buffers. A reader keeps one set and reuses it from take to take; the first kKeptContents samples
// keep their sequences' storage (a sweep a take costs no allocation), the others give it back when
// the set is returned, so a take of a large backlog does not pin its memory. A take while an
// earlier set is still out gets a fresh set.
#pragma once

#include "cdc/dds/types.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

struct ddsi_serdata;

namespace cdc::dds::detail {

class SampleBuffers {
 public:
  explicit SampleBuffers(const dds_topic_descriptor_t* descriptor) : descriptor_(descriptor) {}
  ~SampleBuffers();
  SampleBuffers(const SampleBuffers&) = delete;
  SampleBuffers& operator=(const SampleBuffers&) = delete;

  // Takes up to `max` samples from `reader` (removing them from its cache) into the first buffers,
  // growing the set as needed, and fills infos[0, n). Returns n; adds to `valid` the samples with
  // data and to `bytes` their serialised size (encapsulation header, XCDR body and the padding to
  // 4 bytes, as on the wire). The buffer of an invalid sample (an instance state change) is left
  // as it was. A sample Cyclone cannot deserialise comes back marked as invalid and is counted in
  // `failed`. Throws DdsError (naming `what`) when the take itself fails.
  size_t take(dds_entity_t reader, size_t max, std::vector<dds_sample_info_t>& infos, uint64_t& valid, uint64_t& bytes,
              uint64_t& failed, const char* what);

  const void* operator[](size_t i) const noexcept { return samples_[i]; }

  // Frees what samples [kKeptContents, used) hold and empties them (before the set is reused).
  void recycle(size_t used);
  static constexpr size_t kKeptContents = 4;

 private:
  const dds_topic_descriptor_t* descriptor_;
  std::vector<void*> samples_;          // dds_alloc'ed, zero-initialised, owned
  std::vector<ddsi_serdata*> serdata_;  // what dds_takecdr hands over, kept to spare an allocation per take
};

}  // namespace cdc::dds::detail
