// The decimator's priority queue: a radix heap over the entries' 32-bit cost keys, whose lowest part
// (every entry at or below the last key group it moved up to) is a QuadHeap. A pass pops in cost order
// and the costs it pops rise: an entry far above the last group sits in a bucket by the highest bit in
// which its group differs from the last, appended there in one sequential write, and moves to a lower
// bucket only when the groups below it are gone, a few moves in its life. Only the entries at or below
// the last group are heap-ordered: the fresh edges of the blocks a pass has brought and those near the
// cost it stopped at (about 4,000 entries at 448^3), not every queued edge, whose 4-ary heap walked a
// cache line a level at every pop (docs/perf.md). The pops are those of one exact priority queue in
// T's order: the same collapses, the same bytes.
#pragma once
#include <array>
#include <cstddef>
#include <cstdint>

#include "core/chunked_vector.h"
#include "core/quad_heap.h"

namespace vdb_isosimp {

// T: as QuadHeap's, with `uint32_t costBits() const` such that a < b implies a.costBits() <=
// b.costBits() (the first criterion of the order). The interface is QuadHeap's, cold entries and
// forgetting included (QuadHeap::coolFrom, forgetFrom): a cool bar only keeps its bookkeeping here,
// since entries far above the pops cost nothing until they are reached; a forgetting queue drops what
// is not below its bar, as QuadHeap does.
template <typename T>
class RadixQueue {
    // Keys compare in groups of 2^kGroupBits (1/128 of an octave of a float cost): the heap part takes
    // a whole group at once, so an entry moves at most 31 - kGroupBits times.
    static constexpr unsigned kGroupBits = 16;
    static constexpr unsigned kBuckets = 32 - kGroupBits;
    // Buckets of 2048 entries a chunk (32 KiB, the ChunkPool's smallest, not glibc's heap, whose pages
    // malloc_trim hands back to be faulted in again): a queue holds a part-filled chunk per bucket in
    // use, and there are as many queues as slabs in progress and nodes waiting for their sibling.
    using Bucket = ChunkedVector<T, 11>;
    static uint32_t group(const T& x) { return x.costBits() >> kGroupBits; }

public:
    size_t size() const { return mLow.size() + mHigh; }
    bool empty() const { return size() == 0; }
    void shrinkToFit()
    {
        mLow.shrinkToFit();
        mSpares.clear();
    }
    void dropSpares() { mLow.dropSpares(); }
    void clear()
    {
        mLow.clear();
        for (Bucket& b : mBucket) b.clear();
        mHigh = 0;
        mLast = 0;
        mSpares.clear();
        mHasCold = false;
        mForget = false;
    }

    // Calls f on every entry, freeing the storage as it goes (the heap part's chunks handed to `into`,
    // as QuadHeap::drain); the queue is left empty, forgetting nothing (read forgets() and coldBar first).
    template <typename F>
    void drain(F f, RadixQueue* into = nullptr)
    {
        mLow.drain(f, into ? &into->mLow : nullptr);
        for (Bucket& b : mBucket) {
            for (size_t i = 0; i < b.size(); ++i) {
                f(b[i]);
                b.releaseThrough(i);
            }
        }
        clear();
    }

    // Calls f on every entry, in no particular order.
    template <typename F>
    void visit(F f) const
    {
        mLow.visit(f);
        for (const Bucket& b : mBucket)
            for (size_t i = 0; i < b.size(); ++i) f(b[i]);
    }

    // QuadHeap::coolFrom's bookkeeping (the bar only ever lowers; a forgetting queue drops what is not
    // below the new bar). The bar lapses once nothing below it is left, when the queue is next read.
    void coolFrom(const T& from)
    {
        if (mHasCold && mColdFrom < from) return;
        mColdFrom = from;
        mHasCold = true;
        if (mForget) dropFromBar();
    }
    bool coldBar(T& bar) const
    {
        if (mHasCold) bar = mColdFrom;
        return mHasCold;
    }
    // Drops the entries not below `from` (or below a lower bar already set), and those pushed or
    // appended later, until clear() (QuadHeap::forgetFrom).
    void forgetFrom(const T& from)
    {
        mForget = true;
        if (!(mHasCold && mColdFrom < from)) mColdFrom = from;
        mHasCold = true;
        dropFromBar();
    }
    bool forgets() const { return mForget; }

    void append(const T& x)
    {
        if (!dropped(x)) place(x, true);
    }
    void push(const T& x)
    {
        if (!dropped(x)) place(x, false);
    }

    // The smallest entry. Not empty.
    const T& top()
    {
        ready();
        return mLow.top();
    }

    // Removes and returns the smallest entry. Not empty.
    T pop()
    {
        ready();
        return mLow.pop();
    }

    // Drops the entries `remove` says so of.
    template <typename Pred>
    void eraseIf(Pred remove)
    {
        mLow.eraseIf(remove);
        for (Bucket& b : mBucket) mHigh -= b.eraseIf(remove);
    }

private:
    bool dropped(const T& x) const { return mForget && !(x < mColdFrom); }
    void dropFromBar()
    {
        const T bar = mColdFrom;
        eraseIf([&](const T& x) { return !(x < bar); });
    }

    void place(const T& x, bool append)
    {
        const uint32_t key = group(x);
        if (key <= mLast) {
            if (append) mLow.append(x);
            else mLow.push(x);
            return;
        }
        const unsigned k = 31u - unsigned(__builtin_clz(key ^ mLast));
        mBucket[k].emplace_back(&mSpares) = x;
        ++mHigh;
    }

    // The heap part holds the smallest entry; a cool bar with nothing below it lapses (QuadHeap's
    // cold entries come back then).
    void ready()
    {
        if (mLow.empty()) refill();
        if (mHasCold && !mForget && !(mLow.top() < mColdFrom)) mHasCold = false;
    }

    // The heap part ran empty: the lowest non-empty bucket's least key group is the new last one; its
    // entries of that group go to the heap part, the others to buckets below (they differ from it below
    // bit k).
    __attribute__((noinline)) void refill()
    {
        unsigned k = 0;
        while (mBucket[k].empty()) ++k;
        Bucket& from = mBucket[k];
        mHigh -= from.size();
        uint32_t least = UINT32_MAX;
        for (size_t i = 0; i < from.size(); ++i) least = std::min(least, group(from[i]));
        mLast = least;
        // Its entries all go below bucket k: it is read in place, its chunks serving theirs as it goes.
        for (size_t i = 0; i < from.size(); ++i) {
            place(from[i], true);
            from.releaseThrough(i, &mSpares);
        }
        from.clear();
    }

    QuadHeap<T> mLow;                      // entries whose key group is <= mLast, heap-ordered
    std::array<Bucket, kBuckets> mBucket;  // bucket k: groups above mLast whose highest bit differing from it is k
    size_t mHigh = 0;                      // entries in the buckets (size() is asked at every pop)
    uint32_t mLast = 0;                    // a key group
    typename Bucket::Spares mSpares;       // a chunk a refill has read, for the next bucket that grows
    T mColdFrom{};
    bool mHasCold = false;
    bool mForget = false;  // with mHasCold: what is not below mColdFrom is dropped
};

} // namespace vdb_isosimp
