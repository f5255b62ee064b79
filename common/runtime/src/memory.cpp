#include "cdc/runtime/memory.hpp"

#include <cstdlib>  // the C library's headers define __GLIBC__ when it is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace cdc::runtime {

namespace {
constexpr int kThresholdBytes = 128 * 1024;
}  // namespace

#if !defined(__GLIBC__)
#warning "not glibc: the heap is left to the C library's defaults"
#endif

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
