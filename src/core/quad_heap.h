// The decimator's priority queue: a 4-ary min-heap of 16-byte entries in which every group of four
// siblings fills exactly one 64-byte cache line. Popping walks one group per level, so a level costs
// at most one cache miss (with the groups straddling two lines, as in a plain std::vector, it was often
// two; the sift-down was the decimator's second-hottest function). Half the depth of a binary heap.
#pragma once
#include <cstddef>
#include <new>
#include <vector>

namespace vdb_isosimp {

// Storage aligned to cache lines.
template <typename T>
struct LineAllocator {
    using value_type = T;
    static constexpr std::align_val_t kAlign{64};
    LineAllocator() = default;
    template <typename U>
    LineAllocator(const LineAllocator<U>&) {}
    T* allocate(size_t n) { return static_cast<T*>(::operator new(n * sizeof(T), kAlign)); }
    void deallocate(T* p, size_t) { ::operator delete(p, kAlign); }
    template <typename U>
    bool operator==(const LineAllocator<U>&) const { return true; }
    template <typename U>
    bool operator!=(const LineAllocator<U>&) const { return false; }
};

// T: 16 bytes, with a strict total order `operator<` (the smallest is popped first). Entries may also
// be appended in bulk without order (append()); the heap is built once, on the next push or pop.
template <typename T>
class QuadHeap {
    static_assert(sizeof(T) == 16, "four entries must fill one 64-byte line");
    // Logical entry i sits at mV[i + kPad]; its children 4i+1..4i+4 then start at byte 64(i+1).
    static constexpr size_t kPad = 3;

public:
    QuadHeap() : mV(kPad) {}

    size_t size() const { return mV.size() - kPad; }
    bool empty() const { return size() == 0; }
    void reserve(size_t n) { mV.reserve(n + kPad); }
    void shrinkToFit() { mV.shrink_to_fit(); }
    void clear()
    {
        mV.resize(kPad);
        mUnordered = false;
    }
    // The entries, in no particular order.
    const T* begin() const { return mV.data() + kPad; }
    const T* end() const { return mV.data() + mV.size(); }

    void append(const T& x)
    {
        mV.push_back(x);
        mUnordered = true;
    }

    void push(const T& x)
    {
        order();
        mV.push_back(x);
        size_t i = size() - 1;
        while (i > 0) {
            const size_t parent = (i - 1) / 4;
            if (!(x < at(parent))) break;
            at(i) = at(parent);
            i = parent;
        }
        at(i) = x;
    }

    // Removes and returns the smallest entry. Not empty.
    T pop()
    {
        order();
        const T top = at(0);
        at(0) = mV.back();
        mV.pop_back();
        if (!empty()) siftDown(0);
        return top;
    }

    // Drops the entries `remove` says so of, then rebuilds the heap.
    template <typename Pred>
    void eraseIf(Pred remove)
    {
        size_t kept = kPad;
        for (size_t i = kPad; i < mV.size(); ++i)
            if (!remove(mV[i])) mV[kept++] = mV[i];
        mV.resize(kept);
        mUnordered = true;
        order();
    }

private:
    T& at(size_t i) { return mV[i + kPad]; }

    void order()
    {
        if (!mUnordered) return;
        for (size_t i = size() / 4 + 1; i-- > 0;)
            if (i < size()) siftDown(i);
        mUnordered = false;
    }

    void siftDown(size_t i)
    {
        const T x = at(i);
        const size_t n = size();
        for (;;) {
            const size_t first = 4 * i + 1;
            if (first >= n) break;
            size_t best = first;
            const size_t last = first + 4 < n ? first + 4 : n;
            for (size_t k = first + 1; k < last; ++k)
                if (at(k) < at(best)) best = k;
            if (!(at(best) < x)) break;
            at(i) = at(best);
            i = best;
        }
        at(i) = x;
    }

    std::vector<T, LineAllocator<T>> mV;
    bool mUnordered = false;
};

} // namespace vdb_isosimp
