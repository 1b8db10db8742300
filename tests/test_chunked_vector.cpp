// The decimator's chunked arrays (core/chunked_vector.h): chunks let go of by one array and filled
// again by another, and the process-wide pool of chunk slots in huge-page regions (core/chunk_pool.h).
#include "core/chunk_pool.h"
#include "core/chunked_vector.h"
#include "core/quad_heap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace vdb_isosimp {
namespace {

struct Record {
    double x = 0.0;
    uint32_t id = 0;
};

TEST(ChunkedVector, AChunkLetGoIsFilledAgainByTheNextArray)
{
    using Array = ChunkedVector<Record, 4>;  // chunks of 16
    Array from, into;
    Array::Spares spares;
    for (uint32_t i = 0; i < 48; ++i) from.emplace_back() = {1.5, i};
    const Record* firstChunk = &from[0];
    // Reading the first two chunks through lets them go: the first waits as a spare, the second is
    // freed (at most kMax, 1, wait).
    for (size_t i = 0; i < 32; ++i) from.releaseThrough(i, &spares);
    EXPECT_EQ(spares.size(), Array::Spares::kMax);
    EXPECT_EQ(from[40].id, 40u) << "the chunks not read through stay";
    // The next array's first chunk is the spare, its element value-initialised, not the old content.
    Record& first = into.emplace_back(&spares);
    EXPECT_EQ(spares.size(), 0u);
    EXPECT_EQ(&first, firstChunk);
    EXPECT_EQ(first.id, 0u);
    EXPECT_EQ(first.x, 0.0);
    // Without a spare, a fresh chunk.
    for (uint32_t i = 1; i < 20; ++i) into.emplace_back(&spares).id = i;
    EXPECT_EQ(into.size(), 20u);
    EXPECT_EQ(into[19].id, 19u);
    // Spares are room, not content: a copy of them starts empty.
    Array::Spares more;
    from.releaseThrough(47, &more);
    const Array::Spares copy(more);
    EXPECT_EQ(more.size(), 1u);
    EXPECT_EQ(copy.size(), 0u);
}

TEST(ChunkPool, AFreedSlotIsTheNextOfItsSizeHandedOutAndAnEmptyRegionIsUnmapped)
{
    if (!kChunksInRegions) GTEST_SKIP() << "under AddressSanitizer every chunk is a heap block";
    const size_t mapped = ChunkPool::mappedBytes(), idle = ChunkPool::idleBytes();
    const size_t big = size_t(128) << 10, align = 64;
    void* keep = ChunkPool::allocate(big, align);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(keep) % align, 0u);
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + kHugePage);  // 16 slots of 128 KiB
    EXPECT_EQ(ChunkPool::idleBytes(), idle + 15 * big);
    // A slot let go of is the next one handed out; another size takes a region of its own.
    void* a = ChunkPool::allocate(big, align);
    EXPECT_NE(a, keep);
    ChunkPool::free(a, big, align);
    EXPECT_EQ(ChunkPool::allocate(big, align), a);
    void* other = ChunkPool::allocate(2 * big, align);
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + 2 * kHugePage);
    // Small chunks are glibc's.
    void* small = ChunkPool::allocate(ChunkPool::kMinBytes / 2, align);
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + 2 * kHugePage);
    ChunkPool::free(small, ChunkPool::kMinBytes / 2, align);
    // Filling a region maps the next; every slot is writable and none overlaps another.
    std::vector<char*> slots;
    for (int k = 0; k < 30; ++k) {
        slots.push_back(static_cast<char*>(ChunkPool::allocate(big, align)));
        std::fill(slots.back(), slots.back() + big, char(k));
    }
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + 3 * kHugePage);  // 32 slots of 128 KiB: two regions
    for (int k = 0; k < 30; ++k) {
        EXPECT_EQ(slots[k][0], char(k));
        EXPECT_EQ(slots[k][big - 1], char(k));
    }
    for (char* s : slots) ChunkPool::free(s, big, align);
    ChunkPool::free(a, big, align);
    ChunkPool::free(other, 2 * big, align);
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + kHugePage);  // `keep` holds the first region
    ChunkPool::free(keep, big, align);
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped);
    EXPECT_EQ(ChunkPool::idleBytes(), idle);
}

TEST(ChunkPool, PooledVectorsTakeSlotsOfAFewSizesOrMappingsOfTheirOwn)
{
    if (!kChunksInRegions) GTEST_SKIP() << "under AddressSanitizer every chunk is a heap block";
    const size_t mapped = ChunkPool::mappedBytes();
    PooledVector<uint32_t> keep(70000);  // 280 KiB: a slot of 512 KiB
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + kHugePage);
    const uint32_t* first = nullptr;
    {
        PooledVector<uint32_t> v(100000, 7u);  // 400 KiB: the same size of slot
        first = v.data();
        EXPECT_EQ(reinterpret_cast<uintptr_t>(first) % (size_t(512) << 10), 0u);
    }
    // The next array of that size of slot takes the one let go of, its elements initialised anew.
    PooledVector<uint32_t> w(120000);
    EXPECT_EQ(w.data(), first);
    EXPECT_EQ(w[0], 0u);
    EXPECT_EQ(w[119999], 0u);
    // Small arrays come from the heap, large ones are mappings of whole huge pages outside the pool.
    PooledVector<uint8_t> small(1000, 1);
    PooledVector<uint8_t> large(3 << 20, 1);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(large.data()) % kHugePage, 0u);
    EXPECT_EQ(ChunkPool::mappedBytes(), mapped + kHugePage);
    EXPECT_EQ(size_t(std::count(large.begin(), large.end(), uint8_t(1))), large.size());
}

TEST(ChunkPool, ArraysAndQueuesReuseFreedChunksAsFreshOnes)
{
    if (!kChunksInRegions) GTEST_SKIP() << "under AddressSanitizer every chunk is a heap block";
    using Array = ChunkedVector<Record, 14>;  // 16384 records of 16 bytes: 256 KiB chunks, pooled
    Array holder;
    holder.emplace_back();  // keeps a region of 256 KiB slots mapped
    const size_t idle = ChunkPool::idleBytes();
    std::vector<const Record*> chunks;
    {
        Array a;
        for (uint32_t i = 0; i < 20000; ++i) a.emplace_back() = {2.5, i + 1};
        Array copy(a);  // a deep copy takes chunks of its own
        EXPECT_NE(&copy[0], &a[0]);
        EXPECT_EQ(copy[19999].id, 20000u);
        EXPECT_EQ(ChunkPool::idleBytes(), idle - 4 * Array::kChunk * sizeof(Record));
        chunks = {&a[0], &a[Array::kChunk], &copy[0], &copy[Array::kChunk]};
    }
    EXPECT_EQ(ChunkPool::idleBytes(), idle);
    // A new array takes a slot let go of; what it appends is value-initialised, not the old content.
    Array b;
    for (uint32_t i = 0; i < 3; ++i) {
        const Record& r = b.emplace_back();
        EXPECT_EQ(r.id, 0u);
        EXPECT_EQ(r.x, 0.0);
    }
    EXPECT_NE(std::find(chunks.begin(), chunks.end(), &b[0]), chunks.end());
    EXPECT_EQ(ChunkPool::idleBytes(), idle - Array::kChunk * sizeof(Record));
    // The queue's chunks (256 KiB, cache-line aligned) come and go through the same pool, and a queue
    // on reused chunks still pops in order.
    struct Entry {
        float key;
        uint32_t a, b, c;
        bool operator<(const Entry& o) const { return key < o.key; }
    };
    {
        QuadHeap<Entry> q;
        for (uint32_t i = 0; i < 40000; ++i) q.push({float((i * 7919u) % 40000u), i, 0, 0});
    }
    QuadHeap<Entry> q;
    for (uint32_t i = 0; i < 40000; ++i) q.push({float((i * 104729u) % 40000u), i, 0, 0});
    for (uint32_t i = 0; i < 40000; ++i) {
        ASSERT_EQ(q.top().key, float(i));
        q.pop();
    }
}

} // namespace
} // namespace vdb_isosimp
