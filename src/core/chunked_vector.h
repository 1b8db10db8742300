// A growable array stored in fixed chunks: growing never copies and never holds the old and the new
// buffer at once, and the unused tail is below one chunk. For the decimator's vertex and face arrays,
// where std::vector's doubling left up to half the capacity unused and briefly needed 1.5x more at
// every reallocation (the peak of a run when the slab meshes are merged). Chunks of 4096: every
// decimator of the merge tree (a slab, a node waiting for its sibling) holds a part-filled last chunk
// of each array, and 16384 vertices' geometry alone is 1.7 MB.
#pragma once
#include "core/chunk_pool.h"

#include <algorithm>
#include <cstddef>
#include <memory>
#include <type_traits>
#include <vector>

namespace vdb_isosimp {

// Chunks one array let go of, for another to fill again instead of fresh memory: a fresh chunk of a
// few hundred KiB is mapped on its own, and the kernel faults in and zeroes each of its pages on first
// touch (a merge reads one decimator's arrays while it grows another's). At most kMax wait: a reader
// that lets go of chunks faster than the writer fills them (dead slots, dropped entries) frees the
// rest at once, as without spares. Spare room, not content: a copy starts without any.
template <typename Chunk>
class SpareChunks {
public:
    static constexpr size_t kMax = 1;

    SpareChunks() = default;
    SpareChunks(const SpareChunks&) {}
    SpareChunks& operator=(const SpareChunks&) { return *this; }
    SpareChunks(SpareChunks&&) noexcept = default;
    SpareChunks& operator=(SpareChunks&&) noexcept = default;

    size_t size() const { return mChunks.size(); }
    void clear() { mChunks.clear(); }
    // Keeps the chunk if fewer than kMax wait, frees it otherwise.
    void give(Chunk&& chunk)
    {
        if (mChunks.size() < kMax) mChunks.push_back(std::move(chunk));
        else chunk.reset();
    }
    // A waiting chunk, or fresh() if none waits.
    template <typename Fresh>
    Chunk take(Fresh fresh)
    {
        if (mChunks.empty()) return fresh();
        Chunk c = std::move(mChunks.back());
        mChunks.pop_back();
        return c;
    }

private:
    std::vector<Chunk> mChunks;
};

template <typename T, unsigned Shift = 12>
class ChunkedVector {
    static_assert(std::is_trivially_destructible<T>::value, "a chunk's elements are never destroyed one by one");
    static constexpr size_t kAlign = alignof(T) > __STDCPP_DEFAULT_NEW_ALIGNMENT__ ? alignof(T) : __STDCPP_DEFAULT_NEW_ALIGNMENT__;

public:
    static constexpr size_t kChunk = size_t(1) << Shift;
    // A chunk's memory goes back to the ChunkPool.
    struct Free {
        void operator()(T* p) const { ChunkPool::free(p, kChunk * sizeof(T), kAlign); }
    };
    using Chunk = std::unique_ptr<T[], Free>;

    ChunkedVector() = default;
    ChunkedVector(ChunkedVector&&) noexcept = default;
    ChunkedVector& operator=(ChunkedVector&&) noexcept = default;
    // A deep copy: a LOD chain's coarser level starts from a copy of its slab's finer mesh.
    ChunkedVector(const ChunkedVector& o) : mSize(o.mSize)
    {
        for (size_t k = 0; k < o.mChunks.size(); ++k) {
            const auto& c = o.mChunks[k];
            mChunks.push_back(c ? newChunk() : nullptr);
            // The last chunk's tail was never written.
            const size_t used = mSize > k * kChunk ? std::min(kChunk, mSize - k * kChunk) : 0;
            if (c) std::copy(c.get(), c.get() + used, mChunks.back().get());
        }
    }
    ChunkedVector& operator=(const ChunkedVector& o)
    {
        ChunkedVector copy(o);
        return *this = std::move(copy);
    }

    size_t size() const { return mSize; }
    bool empty() const { return mSize == 0; }
    T& operator[](size_t i) { return mChunks[i >> Shift][i & (kChunk - 1)]; }
    const T& operator[](size_t i) const { return mChunks[i >> Shift][i & (kChunk - 1)]; }

    // Chunks releaseThrough lets go of, for another array's emplace_back.
    using Spares = SpareChunks<Chunk>;

    // Appends a value-initialised element (in a spare chunk, if it needs a chunk and one waits).
    T& emplace_back(Spares* spares = nullptr)
    {
        if (mSize == mChunks.size() * kChunk) {
            mChunks.push_back(spares ? spares->take(newChunk) : newChunk());
        }
        T& x = (*this)[mSize++];
        x = T{};
        return x;
    }

    // Keeps the first n elements (n <= size()) and frees the chunks past them.
    void truncate(size_t n)
    {
        mSize = n;
        mChunks.resize((n + kChunk - 1) >> Shift);
    }
    void clear() { truncate(0); }

    // Drops the elements `remove` says so of, keeping the others' order; returns how many it dropped.
    template <typename Pred>
    size_t eraseIf(Pred remove)
    {
        size_t kept = 0;
        for (size_t i = 0; i < mSize; ++i)
            if (!remove((*this)[i])) (*this)[kept++] = (*this)[i];
        const size_t dropped = mSize - kept;
        truncate(kept);
        return dropped;
    }

    // For an array read once front to back before it is discarded: element i, the last read so far,
    // is done with; its chunk is freed once i is the chunk's last element (nothing before i in that
    // chunk may be accessed again).
    void releaseThrough(size_t i, Spares* spares = nullptr)
    {
        if (((i + 1) & (kChunk - 1)) != 0) return;
        if (spares) spares->give(std::move(mChunks[i >> Shift]));
        else mChunks[i >> Shift].reset();
    }

    template <typename Ref, typename Owner>
    struct Iter {
        Owner* owner;
        size_t i;
        Ref operator*() const { return (*owner)[i]; }
        Iter& operator++() { ++i; return *this; }
        bool operator!=(const Iter& o) const { return i != o.i; }
    };
    Iter<T&, ChunkedVector> begin() { return {this, 0}; }
    Iter<T&, ChunkedVector> end() { return {this, mSize}; }
    Iter<const T&, const ChunkedVector> begin() const { return {this, 0}; }
    Iter<const T&, const ChunkedVector> end() const { return {this, mSize}; }

private:
    // Default-initialised: every element is written as it is appended (emplace_back), so zeroing the
    // chunk first would be a second pass over it (often over pages the kernel has just zeroed; docs/perf.md).
    static Chunk newChunk()
    {
        T* p = static_cast<T*>(ChunkPool::allocate(kChunk * sizeof(T), kAlign));
        std::uninitialized_default_construct_n(p, kChunk);
        return Chunk(p);
    }

    std::vector<Chunk> mChunks;
    size_t mSize = 0;
};

} // namespace vdb_isosimp
