#include "cdc/dds/sample_buffers.hpp"

#include "cdc/dds/error.hpp"

#include <dds/ddsi/ddsi_serdata.h>

#include <cstring>
#include <string>

namespace cdc::dds::detail {

SampleBuffers::~SampleBuffers() {
  for (void* s : samples_) dds_sample_free(s, descriptor_, DDS_FREE_ALL);
}

void SampleBuffers::recycle(size_t used) {
  for (size_t i = kKeptContents; i < used && i < samples_.size(); ++i) {
    dds_sample_free(samples_[i], descriptor_, DDS_FREE_CONTENTS);
    std::memset(samples_[i], 0, descriptor_->m_size);
  }
}

size_t SampleBuffers::take(dds_entity_t reader, size_t max, std::vector<dds_sample_info_t>& infos, uint64_t& valid,
                           uint64_t& bytes, uint64_t& failed, const char* what) {
  while (samples_.size() < max) {
    samples_.push_back(dds_alloc(descriptor_->m_size));  // zero-filled: an empty sample
  }
  infos.resize(max);
  serdata_.assign(max, nullptr);
  const dds_return_t rc = dds_takecdr(reader, serdata_.data(), static_cast<uint32_t>(max), infos.data(), DDS_ANY_STATE);
  if (rc < 0) check(rc, std::string("take on '") + what + "'");  // the message only when it fails
  const auto n = static_cast<size_t>(rc);
  ddsi_serdata** data = serdata_.data();
  for (size_t i = 0; i < n; ++i) {
    // An invalid sample (an instance state change) brings a key-only serdata that may not name
    // its type: its buffer is left as it was, and only its info means anything.
    if (infos[i].valid_data) {
      if (ddsi_serdata_to_sample(data[i], samples_[i], nullptr, nullptr)) {
        ++valid;
        bytes += ddsi_serdata_size(data[i]);
      } else {
        infos[i].valid_data = false;
        ++failed;
      }
    }
    if (data[i] != nullptr) ddsi_serdata_unref(data[i]);
  }
  return n;
}

}  // namespace cdc::dds::detail
