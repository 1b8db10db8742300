// Memory for the chunks of the decimator's arrays and queues (ChunkedVector, QuadHeap), kept for reuse
// within the process instead of going back to the system at once. A chunk of a few hundred KiB is
// mapped on its own by glibc, and every page of a fresh mapping is faulted in and zeroed by the kernel
// on first touch: the merge tree lets go of one node's chunks while it fills another's, and a LOD
// chain's copies and passes do so all run long (docs/perf.md). Up to kMaxCachedBytes of freed chunks
// wait for the next chunk of the same size; beyond that a chunk is freed as before, so the pool adds at
// most that much to the peak.
// Smaller chunks come from glibc's heap, which reuses them itself. Thread-safe.
#pragma once
#include <cstddef>

namespace vdb_isosimp {

class ChunkPool {
public:
    static constexpr size_t kMinBytes = size_t(128) << 10;      // glibc's default mmap threshold
    static constexpr size_t kMaxCachedBytes = size_t(32) << 20;  // the caps measured: docs/perf.md

    // `bytes` aligned to `align` (both the same at free()).
    static void* allocate(size_t bytes, size_t align);
    static void free(void* p, size_t bytes, size_t align) noexcept;
    // Bytes of freed chunks waiting for reuse.
    static size_t cachedBytes();
    // Frees every waiting chunk (at the end of a run: the pool holds nothing between runs).
    static void release();
};

} // namespace vdb_isosimp
