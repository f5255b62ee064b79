// How a long-running service holds its heap. A back-end's graph grows through a mission, and its
// solves and published trajectories need large transient buffers that grow with it: with glibc's
// defaults (a threshold for mapped blocks that rises to the largest block freed, and no trimming
// of free pages within the heap) the process keeps each solve's peak resident for good, and its
// memory grows faster than what it holds.
#pragma once

namespace cdc::runtime {

// Blocks of 128 KiB and more are mapped and unmapped on free, and free memory at the heap's top is
// trimmed beyond 128 KiB (fixed thresholds: glibc's dynamic threshold stops adapting). Called by
// run_node before the node is built; a no-op without glibc.
void return_large_blocks();

// Returns every free page of the heap to the system (glibc's malloc_trim): after a burst of
// transient allocations, such as a whole-graph solve. Costs a pass over the heap's free lists.
void release_free_memory();

}  // namespace cdc::runtime
