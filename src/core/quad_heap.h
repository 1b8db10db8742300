// The decimator's priority queue: a 4-ary min-heap of 16-byte entries in which every group of four
// siblings fills exactly one 64-byte cache line. Popping walks one group per level, so a level costs
// at most one cache miss (with the groups straddling two lines, as in a plain std::vector, it was often
// two; the sift-down was the decimator's second-hottest function). Half the depth of a binary heap.
#pragma once
#include <algorithm>
#include <cstddef>
#include <memory>
#include <new>
#include <vector>

#include "core/chunked_vector.h"

namespace vdb_isosimp {

// T: 16 bytes, with a strict total order `operator<` (the smallest is popped first). Entries may also
// be appended in bulk without order (append()); the heap is built once, on the next push or pop.
// Stored in chunks aligned to cache lines, like the decimator's vertex and face arrays: growing never
// copies, so a merge that appends a child's queue to its sibling's never holds the old and the new
// array at once. A chunk is 256 KiB: freed, it waits in the ChunkPool for another heap's next chunk or
// goes back to the system, as its own mapping, at once.
template <typename T>
class QuadHeap {
    static_assert(sizeof(T) == 16, "four entries must fill one 64-byte line");
    static constexpr unsigned kShift = 14;
    static constexpr size_t kChunk = size_t(1) << kShift;  // a multiple of 4: no sibling group straddles two
    // Logical entry i sits at position i + kPad; its children 4i+1..4i+4 then start at byte 64(i+1).
    static constexpr size_t kPad = 3;
    static constexpr std::align_val_t kAlign{64};
    struct Free {
        void operator()(T* p) const { ChunkPool::free(p, kChunk * sizeof(T), size_t(kAlign)); }
    };
    using Chunk = std::unique_ptr<T[], Free>;
    static Chunk newChunk() { return Chunk(static_cast<T*>(ChunkPool::allocate(kChunk * sizeof(T), size_t(kAlign)))); }

public:
    QuadHeap() = default;
    QuadHeap(QuadHeap&&) noexcept = default;
    QuadHeap& operator=(QuadHeap&&) noexcept = default;
    // A deep copy: a LOD chain's coarser level starts from a copy of its slab's decimator.
    QuadHeap(const QuadHeap& o)
        : mEnd(o.mEnd), mUnordered(o.mUnordered), mCold(o.mCold), mColdFrom(o.mColdFrom), mHasCold(o.mHasCold), mForget(o.mForget)
    {
        for (size_t c = 0; c < o.mChunks.size(); ++c) {
            mChunks.push_back(newChunk());
            const size_t used = c * kChunk < mEnd ? std::min(kChunk, mEnd - c * kChunk) : 0;  // entries written there
            std::copy(o.mChunks[c].get(), o.mChunks[c].get() + used, mChunks.back().get());
        }
    }
    QuadHeap& operator=(const QuadHeap& o)
    {
        QuadHeap copy(o);
        return *this = std::move(copy);
    }

    size_t size() const { return hot() + mCold.size(); }
    bool empty() const { return size() == 0; }
    // Frees the chunks past the entries.
    void shrinkToFit()
    {
        const size_t used = (mEnd + kChunk - 1) >> kShift;
        if (mChunks.size() > used) mChunks.resize(used);
        mCold.truncate(mCold.size());
    }
    // Frees the chunks another heap's drain handed over that no push has filled.
    void dropSpares() { mSpare.clear(); }
    void clear()
    {
        mEnd = kPad;
        mUnordered = false;
        mCold.clear();
        mHasCold = false;
        mForget = false;
    }

    // Entry i of the heap proper (i < size() while nothing is cold), in no particular order unless the
    // heap is ordered.
    const T& entry(size_t i) const { return slot(i + kPad); }

    // Calls f on every entry (the ordered part in array order, then the cold ones in the order they
    // went cold), freeing the storage as it goes, or handing each chunk to heap `into` to fill again as
    // it grows (SpareChunks); the heap is left empty, forgetting nothing (read forgets() and coldBar first).
    template <typename F>
    void drain(F f, QuadHeap* into = nullptr)
    {
        for (size_t p = kPad; p < mEnd; ++p) {
            f(slot(p));
            if (((p + 1) & (kChunk - 1)) != 0) continue;
            if (into) into->mSpare.give(std::move(mChunks[p >> kShift]));
            else mChunks[p >> kShift].reset();
        }
        for (size_t i = 0; i < mCold.size(); ++i) {
            f(mCold[i]);
            mCold.releaseThrough(i);
        }
        mChunks.clear();
        clear();
    }

    // Calls f on every entry, in no particular order.
    template <typename F>
    void visit(F f) const
    {
        for (size_t p = kPad; p < mEnd; ++p) f(slot(p));
        for (size_t i = 0; i < mCold.size(); ++i) f(mCold[i]);
    }

    // Entries not below `from` wait unordered, outside the heap, until the heap holds nothing smaller
    // (then all of them come back at once): pops and pushes walk a heap of the entries a pass is
    // likely to reach, not of every queued one. The order of pops is the same. With entries already
    // waiting, `from` only ever lowers the bar (raising it would put waiting entries below it).
    void coolFrom(const T& from)
    {
        if (mHasCold && mColdFrom < from) return;
        mColdFrom = from;
        mHasCold = true;
        size_t kept = kPad;
        for (size_t p = kPad; p < mEnd; ++p) {
            if (slot(p) < from) slot(kept++) = slot(p);
            else keepCold(slot(p));
        }
        // Nothing moved (the bar was above every entry): the heap is as ordered as before.
        if (kept != mEnd) mUnordered = true;
        mEnd = kept;
    }

    // The bar of coolFrom, if entries wait outside the heap.
    bool coldBar(T& bar) const
    {
        if (mHasCold) bar = mColdFrom;
        return mHasCold;
    }

    // As coolFrom, but the entries not below `from` are dropped, those pushed or appended later too,
    // until clear(): the owner, which can list every entry again, does so when the heap runs empty
    // (forgets()). Near the top of the merge tree most of a queue lies above the bar and is never
    // popped, yet it was a quarter of the peak memory (docs/perf.md).
    void forgetFrom(const T& from)
    {
        mForget = true;
        coolFrom(from);
        mCold = {};
    }
    bool forgets() const { return mForget; }

    void append(const T& x)
    {
        if (goesCold(x)) {
            keepCold(x);
            return;
        }
        pushBack(x);
        mUnordered = true;
    }

    void push(const T& x)
    {
        if (goesCold(x)) {
            keepCold(x);
            return;
        }
        order();
        pushBack(x);
        size_t i = hot() - 1;
        while (i > 0) {
            const size_t parent = (i - 1) / 4;
            if (!(x < at(parent))) break;
            at(i) = at(parent);
            i = parent;
        }
        at(i) = x;
    }

    // The smallest entry. Not empty.
    const T& top()
    {
        ready();
        return at(0);
    }

    // Removes and returns the smallest entry. Not empty.
    T pop()
    {
        ready();
        const T top = at(0);
        at(0) = slot(--mEnd);
        // Keeps one spare chunk, so pushes and pops at a chunk boundary do not allocate each time.
        if (mChunks.size() > ((mEnd + kChunk - 1) >> kShift) + 1) mChunks.pop_back();
        if (hot() > 0) siftDown(0);
        return top;
    }

    // Drops the entries `remove` says so of, then rebuilds the heap.
    template <typename Pred>
    void eraseIf(Pred remove)
    {
        size_t kept = kPad;
        for (size_t p = kPad; p < mEnd; ++p)
            if (!remove(slot(p))) slot(kept++) = slot(p);
        mEnd = kept;
        mCold.eraseIf(remove);
        shrinkToFit();
        mUnordered = true;
        order();
    }

private:
    size_t hot() const { return mEnd - kPad; }
    bool goesCold(const T& x) const { return mHasCold && !(x < mColdFrom); }
    // An entry not below the bar waits outside the heap, or is dropped if the heap forgets.
    void keepCold(const T& x)
    {
        if (!mForget) mCold.emplace_back() = x;
    }
    // Ordered, with the smallest entry on top: the cold entries come back when none below them is left.
    void ready()
    {
        order();
        if (mHasCold && !mForget && !(hot() > 0 && at(0) < mColdFrom)) warmUp();
    }
    // Out of line: ready() runs twice a pop, this once in thousands.
    __attribute__((noinline)) void warmUp()
    {
        for (size_t i = 0; i < mCold.size(); ++i) {
            pushBack(mCold[i]);
            mCold.releaseThrough(i);
        }
        mCold = {};
        mHasCold = false;
        mUnordered = true;
        order();
    }

    T& slot(size_t p) { return mChunks[p >> kShift][p & (kChunk - 1)]; }
    const T& slot(size_t p) const { return mChunks[p >> kShift][p & (kChunk - 1)]; }
    T& at(size_t i) { return slot(i + kPad); }

    void pushBack(const T& x)
    {
        if ((mEnd >> kShift) == mChunks.size()) mChunks.push_back(mSpare.take(newChunk));
        slot(mEnd++) = x;
    }

    void order()
    {
        if (mUnordered) heapify();
    }
    __attribute__((noinline)) void heapify()
    {
        for (size_t i = hot() / 4 + 1; i-- > 0;)
            if (i < hot()) siftDown(i);
        mUnordered = false;
    }

    void siftDown(size_t i)
    {
        const T x = at(i);
        const size_t n = hot();
        T* hole = &at(i);
        for (;;) {
            const size_t first = 4 * i + 1;
            if (first >= n) break;
            // The four siblings share one line, hence one chunk: one lookup per level.
            T* group = &at(first);
            const size_t count = n - first < 4 ? n - first : 4;
            // Their children's groups start loading while these four are compared: in a queue of
            // millions (a merge near the tree's root, a final pass) every level is a cache miss, and
            // the next level's line no longer waits for this level's choice (docs/perf.md).
            // Their groups are the 16 entries from logical 4 * first + 1, four lines in a row: one
            // lookup for all four unless they straddle two chunks.
            const size_t grandchildren = 4 * first + 1;
            if (grandchildren < n) {
                const size_t p = grandchildren + kPad;
                const T* line = &slot(p);
                if ((p & (kChunk - 1)) <= kChunk - 16) {
                    for (int k = 0; k < 16; k += 4) __builtin_prefetch(line + k);
                } else {
                    for (size_t k = 0; k < 16 && grandchildren + k < n; k += 4) __builtin_prefetch(&slot(p + k));
                }
            }
            size_t best = 0;
            for (size_t k = 1; k < count; ++k)
                if (group[k] < group[best]) best = k;
            if (!(group[best] < x)) break;
            *hole = group[best];
            hole = group + best;
            i = first + best;
        }
        *hole = x;
    }

    std::vector<Chunk> mChunks;
    SpareChunks<Chunk> mSpare;  // chunks another heap's drain handed over (drain), until dropSpares
    size_t mEnd = kPad;
    bool mUnordered = false;
    ChunkedVector<T> mCold;  // entries not below mColdFrom, while mHasCold (coolFrom)
    T mColdFrom{};
    bool mHasCold = false;
    bool mForget = false;  // with mHasCold: what goes cold is dropped (forgetFrom)
};

} // namespace vdb_isosimp
