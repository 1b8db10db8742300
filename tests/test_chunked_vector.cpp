// The decimator's chunked arrays (core/chunked_vector.h): chunks let go of by one array and filled
// again by another, and the process-wide pool of freed chunks (core/chunk_pool.h).
#include "core/chunk_pool.h"
#include "core/chunked_vector.h"
#include "core/quad_heap.h"

#include <gtest/gtest.h>

#include <cstdint>

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

TEST(ChunkPool, AFreedChunkWaitsForTheNextOfItsSizeUpToTheCap)
{
    ChunkPool::release();
    const size_t big = ChunkPool::kMinBytes, align = 64;
    void* a = ChunkPool::allocate(big, align);
    ChunkPool::free(a, big, align);
    EXPECT_EQ(ChunkPool::cachedBytes(), big);
    // Another size or alignment does not take it; the same size does.
    void* other = ChunkPool::allocate(2 * big, align);
    EXPECT_NE(other, a);
    void* odd = ChunkPool::allocate(big, 16);
    EXPECT_NE(odd, a);
    EXPECT_EQ(ChunkPool::allocate(big, align), a);
    EXPECT_EQ(ChunkPool::cachedBytes(), 0u);
    ChunkPool::free(a, big, align);
    ChunkPool::free(other, 2 * big, align);
    ChunkPool::free(odd, big, 16);
    EXPECT_EQ(ChunkPool::cachedBytes(), 4 * big);
    // Small chunks are glibc's to reuse: none waits.
    void* small = ChunkPool::allocate(big / 2, align);
    ChunkPool::free(small, big / 2, align);
    EXPECT_EQ(ChunkPool::cachedBytes(), 4 * big);
    // Never more than the cap waits, however many are freed at once.
    std::vector<void*> many;
    for (size_t k = 0; k < 2 * ChunkPool::kMaxCachedBytes / big; ++k) many.push_back(ChunkPool::allocate(big, 32));
    for (void* p : many) ChunkPool::free(p, big, 32);
    EXPECT_LE(ChunkPool::cachedBytes(), ChunkPool::kMaxCachedBytes);
    EXPECT_GT(ChunkPool::cachedBytes(), ChunkPool::kMaxCachedBytes - big);
    ChunkPool::release();
    EXPECT_EQ(ChunkPool::cachedBytes(), 0u);
}

TEST(ChunkPool, ArraysAndQueuesReuseFreedChunksAsFreshOnes)
{
    ChunkPool::release();
    using Array = ChunkedVector<Record, 14>;  // 16384 records of 16 bytes: 256 KiB chunks, pooled
    const Record* firstChunk = nullptr;
    {
        Array a;
        for (uint32_t i = 0; i < 20000; ++i) a.emplace_back() = {2.5, i + 1};
        firstChunk = &a[0];
        Array copy(a);  // a deep copy takes chunks of its own
        EXPECT_NE(&copy[0], firstChunk);
        EXPECT_EQ(copy[19999].id, 20000u);
    }
    EXPECT_EQ(ChunkPool::cachedBytes(), 4 * Array::kChunk * sizeof(Record));
    // A new array takes a waiting chunk; what it appends is value-initialised, not the old content.
    Array b;
    for (uint32_t i = 0; i < 3; ++i) {
        const Record& r = b.emplace_back();
        EXPECT_EQ(r.id, 0u);
        EXPECT_EQ(r.x, 0.0);
    }
    EXPECT_EQ(ChunkPool::cachedBytes(), 3 * Array::kChunk * sizeof(Record));
    // The queue's chunks (256 KiB, cache-line aligned) come and go through the same pool, and a queue
    // on reused chunks still pops in order.
    struct Entry {
        float key;
        uint32_t a, b, c;
        bool operator<(const Entry& o) const { return key < o.key; }
    };
    ChunkPool::release();
    {
        QuadHeap<Entry> q;
        for (uint32_t i = 0; i < 40000; ++i) q.push({float((i * 7919u) % 40000u), i, 0, 0});
    }
    const size_t cached = ChunkPool::cachedBytes();
    EXPECT_GT(cached, 0u);
    QuadHeap<Entry> q;
    for (uint32_t i = 0; i < 40000; ++i) q.push({float((i * 104729u) % 40000u), i, 0, 0});
    EXPECT_LT(ChunkPool::cachedBytes(), cached);
    for (uint32_t i = 0; i < 40000; ++i) {
        ASSERT_EQ(q.top().key, float(i));
        q.pop();
    }
    ChunkPool::release();
}

} // namespace
} // namespace vdb_isosimp
