// Memory for the decimator's arrays and queues: the chunks of ChunkedVector and QuadHeap, and the
// arrays of one entry per vertex or face that every join builds and drops (PooledVector).
// A run lets go of and takes again hundreds of megabytes of these: fresh memory is a page fault on the
// first touch of every 4 KiB page, which costs about 13 us on the virtual machines these runs are
// measured on (docs/perf.md). So chunks of kMinBytes or more are slots of equal size in 2 MiB-aligned
// regions that ask for transparent huge pages (core/huge_pages.h): one fault maps 2 MiB, and a slot let
// go of is the next one handed out in its region, without a fault. A region is unmapped once none of
// its slots is in use. Smaller chunks come from glibc's heap, which reuses them itself. Thread-safe.
#pragma once
#include "core/huge_pages.h"

#include <cstddef>
#include <new>
#include <vector>

// Under AddressSanitizer every chunk and array is a heap block of its own, so that it sees each one's
// bounds and lifetime; the regions would hide them.
#if defined(__SANITIZE_ADDRESS__)
#define VDB_ISOSIMP_HEAP_CHUNKS 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define VDB_ISOSIMP_HEAP_CHUNKS 1
#endif
#endif

namespace vdb_isosimp {

#ifdef VDB_ISOSIMP_HEAP_CHUNKS
constexpr bool kChunksInRegions = false;
#else
constexpr bool kChunksInRegions = true;
#endif

class ChunkPool {
public:
    static constexpr size_t kMinBytes = size_t(32) << 10;

    // `bytes` aligned to `align` (both the same at free()).
    static void* allocate(size_t bytes, size_t align);
    static void free(void* p, size_t bytes, size_t align) noexcept;
    // Bytes of the regions' slots not in use, and of the regions mapped (for tests and reports).
    static size_t idleBytes();
    static size_t mappedBytes();
};

// An allocator for the decimator's arrays of one entry per vertex or face: under 128 KiB from the heap;
// up to 1 MiB a pool chunk of the next power of two (a handful of sizes, so a dropped array's slot
// serves the next); larger, a mapping of its own in huge pages.
template <typename T>
struct PoolAllocator {
    using value_type = T;
    static constexpr size_t kPooledFrom = size_t(128) << 10;
    static constexpr size_t kMappedFrom = size_t(1) << 20;

    PoolAllocator() = default;
    template <typename U>
    PoolAllocator(const PoolAllocator<U>&) noexcept {}

    static size_t rounded(size_t bytes)
    {
        if (bytes > kMappedFrom) return (bytes + kHugePage - 1) / kHugePage * kHugePage;
        size_t r = kPooledFrom;
        while (r < bytes) r *= 2;
        return r;
    }
    T* allocate(size_t n)
    {
        const size_t bytes = n * sizeof(T);
        if (bytes < kPooledFrom || !kChunksInRegions) return static_cast<T*>(::operator new(bytes));
        if (bytes > kMappedFrom) return static_cast<T*>(mapHugePages(rounded(bytes)));
        return static_cast<T*>(ChunkPool::allocate(rounded(bytes), kAlign));
    }
    void deallocate(T* p, size_t n) noexcept
    {
        const size_t bytes = n * sizeof(T);
        if (bytes < kPooledFrom || !kChunksInRegions) ::operator delete(p);
        else if (bytes > kMappedFrom) unmapHugePages(p, rounded(bytes));
        else ChunkPool::free(p, rounded(bytes), kAlign);
    }
    template <typename U>
    bool operator==(const PoolAllocator<U>&) const noexcept { return true; }
    template <typename U>
    bool operator!=(const PoolAllocator<U>&) const noexcept { return false; }

private:
    static constexpr size_t kAlign = 64;
};

template <typename T>
using PooledVector = std::vector<T, PoolAllocator<T>>;

} // namespace vdb_isosimp
