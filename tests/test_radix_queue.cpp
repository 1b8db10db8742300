// The decimator's queue (core/radix_queue.h) against QuadHeap, its previous queue and its heap part
// (tested against a sorted reference in test_quad_heap.cpp): the same operations, from pushes and
// pops to cool bars, forgetting, erasures, copies and drains, must give the same pops, sizes and bars,
// so the decimator's collapses cannot change with the queue.
#include "core/quad_heap.h"
#include "core/radix_queue.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

namespace vdb_isosimp {
namespace {

// Like the decimator's Candidate: a float cost's bits over a 32-bit id, then a second id.
struct Entry {
    uint64_t key;
    uint32_t b, stamp;
    uint32_t costBits() const { return uint32_t(key >> 32); }
    bool operator<(const Entry& o) const { return key != o.key ? key < o.key : b < o.b; }
    bool operator==(const Entry& o) const { return key == o.key && b == o.b && stamp == o.stamp; }
};

uint32_t bitsOf(float f)
{
    uint32_t bits;
    std::memcpy(&bits, &f, sizeof bits);
    return bits;
}

// Costs as a pass sees them: spread over many octaves, some exactly zero (flat regions), many equal.
class Costs {
public:
    explicit Costs(uint64_t seed) : mRng(seed) {}
    Entry next(float floor = 0.0f)
    {
        float cost;
        switch (mRng() % 8) {
        case 0: cost = 0.0f; break;
        case 1: cost = float(1e-6 * double(mRng() % 4)); break;  // ties
        default: cost = float(std::exp(std::uniform_real_distribution<double>(-25.0, 5.0)(mRng))); break;
        }
        cost = std::max(cost, floor);
        ++mId;
        return {uint64_t(bitsOf(cost)) << 32 | (mId % 977), mId, uint32_t(mRng())};
    }
    uint64_t pick() { return mRng(); }

private:
    std::mt19937_64 mRng;
    uint32_t mId = 0;
};

float costOf(const Entry& e)
{
    const uint32_t bits = e.costBits();
    float f;
    std::memcpy(&f, &bits, sizeof f);
    return f;
}

void expectSame(RadixQueue<Entry>& queue, QuadHeap<Entry>& heap, const char* where)
{
    ASSERT_EQ(queue.size(), heap.size()) << where;
    ASSERT_EQ(queue.forgets(), heap.forgets()) << where;
    Entry a{}, b{};
    ASSERT_EQ(queue.coldBar(a), heap.coldBar(b)) << where;
    if (heap.coldBar(b)) {
        ASSERT_EQ(a.key, b.key) << where;
    }
}

// Pops n entries from both (fewer if they run empty), checking top() and pop() agree.
void popBoth(RadixQueue<Entry>& queue, QuadHeap<Entry>& heap, size_t n, float* last = nullptr)
{
    for (size_t i = 0; i < n && !heap.empty(); ++i) {
        ASSERT_FALSE(queue.empty());
        ASSERT_EQ(queue.top(), heap.top());
        const Entry got = queue.pop();
        ASSERT_EQ(got, heap.pop()) << "pop " << i;
        if (last) *last = costOf(got);
    }
}

TEST(RadixQueue, PopsAsQuadHeapDoesThroughEveryOperation)
{
    Costs costs(3);
    RadixQueue<Entry> queue;
    QuadHeap<Entry> heap;
    float last = 0.0f;
    for (int round = 0; round < 60; ++round) {
        // A pass: new blocks' edges (anywhere, most below the last cost), then pops with re-pushes at
        // a higher cost (stale entries), as decimateTo makes them.
        const bool append = round % 4 == 1;
        for (int i = 0; i < 700; ++i) {
            const Entry e = costs.next();
            if (append) {
                queue.append(e);
                heap.append(e);
            } else {
                queue.push(e);
                heap.push(e);
            }
        }
        expectSame(queue, heap, "after pushes");
        for (int i = 0; i < 500 && !heap.empty(); ++i) {
            popBoth(queue, heap, 1, &last);
            if (costs.pick() % 3 == 0) {
                const Entry e = costs.next(last * 1.5f);
                queue.push(e);
                heap.push(e);
            }
        }
        // The end of a pass: a cool bar or a forgetting one at the next octave above the top, or
        // elsewhere; now and then an erasure, a copy, a clear.
        if (!heap.empty()) {
            const uint32_t exponent = heap.top().costBits() >> 23;
            const Entry bars[] = {{uint64_t((exponent + 1) << 23) << 32, 0, 0}, heap.top(),
                                  {uint64_t(bitsOf(costOf(heap.top()) * 4)) << 32, 0, 0}, costs.next()};
            const Entry bar = bars[round % 4];
            if (round % 9 == 8) {
                queue.forgetFrom(bar);
                heap.forgetFrom(bar);
            } else if (round % 2 == 0) {
                queue.coolFrom(bar);
                heap.coolFrom(bar);
            }
        }
        expectSame(queue, heap, "after a bar");
        if (round % 7 == 3) {
            queue.eraseIf([](const Entry& e) { return e.b % 5 == 0; });
            heap.eraseIf([](const Entry& e) { return e.b % 5 == 0; });
            expectSame(queue, heap, "after an erasure");
        }
        if (round % 10 == 5) {
            // A copy (a LOD chain's coarser level) goes on as the original does.
            RadixQueue<Entry> queueCopy(queue);
            QuadHeap<Entry> heapCopy(heap);
            popBoth(queueCopy, heapCopy, 2000);
            expectSame(queueCopy, heapCopy, "a copy");
        }
        if (round % 20 == 19) {
            queue.clear();
            heap.clear();
            last = 0.0f;
        }
    }
    popBoth(queue, heap, heap.size());
    EXPECT_TRUE(queue.empty());
}

TEST(RadixQueue, ADrainHandsOverEveryEntryOnceIntoAnotherQueue)
{
    // A merge drains one queue into another (drain's `into`), dropping some entries: what arrives pops
    // as a QuadHeap given the same entries.
    Costs costs(9);
    RadixQueue<Entry> from, into;
    QuadHeap<Entry> reference;
    for (int i = 0; i < 60000; ++i) {
        const Entry e = costs.next();
        from.push(e);
        if (i % 2 == 0) {
            const Entry f = costs.next();
            into.push(f);
            reference.push(f);
        }
    }
    for (int i = 0; i < 20000; ++i) from.pop();  // its buckets part-moved
    const size_t before = from.size();
    size_t seen = 0;
    from.drain(
        [&](const Entry& e) {
            ++seen;
            if (e.b % 3 == 0) return;
            into.push(e);
            reference.push(e);
        },
        &into);
    EXPECT_EQ(seen, before);
    EXPECT_TRUE(from.empty());
    EXPECT_FALSE(from.forgets());
    into.dropSpares();
    ASSERT_EQ(into.size(), reference.size());
    while (!reference.empty()) ASSERT_EQ(into.pop(), reference.pop());
    EXPECT_TRUE(into.empty());
    from.push(costs.next());  // usable again after a drain
    EXPECT_EQ(from.size(), 1u);
}

TEST(RadixQueue, VisitSeesEveryEntryOnce)
{
    Costs costs(21);
    RadixQueue<Entry> queue;
    std::vector<uint32_t> pushed, seen;
    for (int i = 0; i < 30000; ++i) {
        const Entry e = costs.next();
        queue.push(e);
        pushed.push_back(e.b);
    }
    std::vector<uint32_t> popped;
    for (int i = 0; i < 10000; ++i) popped.push_back(queue.pop().b);
    queue.visit([&](const Entry& e) { seen.push_back(e.b); });
    seen.insert(seen.end(), popped.begin(), popped.end());
    std::sort(pushed.begin(), pushed.end());
    std::sort(seen.begin(), seen.end());
    EXPECT_EQ(seen, pushed);
}

} // namespace
} // namespace vdb_isosimp
