#include "cdc/runtime/memory.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace cdc::runtime {

namespace {
constexpr int kThresholdBytes = 128 * 1024;
}  // namespace

void return_large_blocks() {
#if defined(__GLIBC__)
  mallopt(M_MMAP_THRESHOLD, kThresholdBytes);
  mallopt(M_TRIM_THRESHOLD, kThresholdBytes);
#endif
}

void release_free_memory() {
#if defined(__GLIBC__)
  malloc_trim(0);
#endif
}

}  // namespace cdc::runtime
