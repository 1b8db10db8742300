// The decimator's queue (core/quad_heap.h): a 4-ary heap against a sorted reference, and its layout.
#include "core/quad_heap.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

namespace vdb_isosimp {
namespace {

struct Entry {
    uint64_t key;
    uint32_t id, pad;
    bool operator<(const Entry& o) const { return key != o.key ? key < o.key : id < o.id; }
};

// Pops the heap and the reference (sorted here, descending: the smallest at the back) and checks that
// both give the same entry; top() is what the next pop returns, also right after unordered appends.
void popBoth(QuadHeap<Entry>& heap, std::vector<Entry>& reference)
{
    std::sort(reference.begin(), reference.end(), [](const Entry& a, const Entry& b) { return b < a; });
    const Entry top = heap.top();
    const Entry got = heap.pop();
    ASSERT_EQ(top.id, got.id);
    ASSERT_EQ(got.key, reference.back().key);
    ASSERT_EQ(got.id, reference.back().id);
    reference.pop_back();
}

// Adds `count` entries with keys below `keys` (many equal: the id breaks ties) to the heap, pushed or
// appended, and to the reference.
void addBoth(QuadHeap<Entry>& heap, std::vector<Entry>& reference, std::mt19937_64& rng, uint32_t& id, int count,
             uint64_t keys, bool append)
{
    for (int i = 0; i < count; ++i) {
        const Entry e{rng() % keys, id++, 0};
        if (append) heap.append(e);
        else heap.push(e);
        reference.push_back(e);
    }
}

TEST(QuadHeap, PopsInOrderWithPushesAppendsAndErasesMixed)
{
    std::mt19937_64 rng(7);
    QuadHeap<Entry> heap;
    std::vector<Entry> reference;
    uint32_t id = 0;
    for (int round = 0; round < 20; ++round) {
        addBoth(heap, reference, rng, id, 500, 1000, round % 3 == 1);
        if (round % 5 == 4) {
            heap.eraseIf([](const Entry& e) { return e.id % 3 == 0; });
            reference.erase(std::remove_if(reference.begin(), reference.end(), [](const Entry& e) { return e.id % 3 == 0; }),
                            reference.end());
        }
        ASSERT_EQ(heap.size(), reference.size());
        for (int i = 0; i < 200; ++i) popBoth(heap, reference);
    }
    while (!heap.empty()) popBoth(heap, reference);
    EXPECT_TRUE(reference.empty());
}

TEST(QuadHeap, ColdEntriesComeBackInOrder)
{
    // coolFrom moves the entries not below a bar out of the heap; pops, pushes, appends, erasures, a
    // copy and a drain must see one queue all the same, whether the bar is below, at or above the top.
    std::mt19937_64 rng(13);
    QuadHeap<Entry> heap;
    std::vector<Entry> reference;
    uint32_t id = 0;
    for (int round = 0; round < 30; ++round) {
        addBoth(heap, reference, rng, id, 400, 2000, round % 4 == 1);
        if (!heap.empty()) {
            const uint64_t top = heap.top().key;
            const uint64_t bars[] = {top, top + 1, top + 300, top > 50 ? top - 50 : 0, rng() % 2000};
            heap.coolFrom(Entry{bars[round % 5], 0, 0});
        }
        ASSERT_EQ(heap.size(), reference.size());
        if (round % 7 == 6) {
            heap.eraseIf([](const Entry& e) { return e.id % 5 == 0; });
            reference.erase(std::remove_if(reference.begin(), reference.end(), [](const Entry& e) { return e.id % 5 == 0; }),
                            reference.end());
            ASSERT_EQ(heap.size(), reference.size());
        }
        if (round % 10 == 9) {
            // A copy (a LOD chain's coarser level) pops the same sequence as the original.
            QuadHeap<Entry> copy(heap);
            std::vector<Entry> copyReference = reference;
            for (int i = 0; i < 300 && !copy.empty(); ++i) popBoth(copy, copyReference);
        }
        for (int i = 0; i < 250 && !heap.empty(); ++i) popBoth(heap, reference);
    }
    // A drain (a merge's piece) hands over every entry, cold ones included, once.
    std::vector<uint32_t> drained, expected;
    heap.drain([&](const Entry& e) { drained.push_back(e.id); });
    for (const Entry& e : reference) expected.push_back(e.id);
    std::sort(drained.begin(), drained.end());
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(drained, expected);
    EXPECT_TRUE(heap.empty());
}

TEST(QuadHeap, AForgettingHeapHoldsOnlyWhatLiesBelowItsBar)
{
    // forgetFrom drops the entries not below the bar, and those pushed or appended later; the rest
    // pop in order. A lower bar drops more, a higher one none back; a copy forgets alike; clear() and a
    // drain end the forgetting. (The decimator lists the dropped edges again: test_decimator.cpp.)
    std::mt19937_64 rng(17);
    QuadHeap<Entry> heap;
    std::vector<Entry> reference;
    uint32_t id = 0;
    addBoth(heap, reference, rng, id, 3000, 1000, false);
    const auto below = [&](uint64_t bar) {
        reference.erase(std::remove_if(reference.begin(), reference.end(), [&](const Entry& e) { return e.key >= bar; }),
                        reference.end());
    };
    heap.forgetFrom(Entry{600, 0, 0});
    below(600);
    EXPECT_TRUE(heap.forgets());
    Entry bar;
    ASSERT_TRUE(heap.coldBar(bar));
    EXPECT_EQ(bar.key, 600u);
    ASSERT_EQ(heap.size(), reference.size());
    for (int round = 0; round < 6; ++round) {
        addBoth(heap, reference, rng, id, 400, 1000, round % 2 == 1);
        below(round < 3 ? 600 : 400);
        if (round == 3) heap.forgetFrom(Entry{400, 0, 0});
        if (round == 4) heap.forgetFrom(Entry{900, 0, 0});  // no higher bar: nothing comes back
        if (round == 5) heap.coolFrom(Entry{300, 0, 0});   // cooling a forgetting heap forgets
        if (round == 5) below(300);
        ASSERT_EQ(heap.size(), reference.size()) << round;
        QuadHeap<Entry> copy(heap);
        std::vector<Entry> copyReference = reference;
        EXPECT_TRUE(copy.forgets());
        copy.push(Entry{999, id, 0});
        while (!copy.empty()) popBoth(copy, copyReference);
        EXPECT_TRUE(copyReference.empty());
        for (int i = 0; i < 150 && !heap.empty(); ++i) popBoth(heap, reference);
    }
    heap.drain([](const Entry&) {});
    EXPECT_FALSE(heap.forgets());
    heap.push(Entry{999, id, 0});
    EXPECT_EQ(heap.size(), 1u) << "a drained heap keeps what is pushed";
    heap.forgetFrom(Entry{100, 0, 0});
    EXPECT_TRUE(heap.empty());
    heap.clear();
    EXPECT_FALSE(heap.forgets());
}

TEST(QuadHeap, GrowsAndShrinksAcrossChunks)
{
    // Entries live in chunks of 16384: push and pop well past several chunk boundaries, up and down
    // twice, and drain what is left in array order.
    std::mt19937_64 rng(11);
    QuadHeap<Entry> heap;
    std::vector<Entry> reference;
    uint32_t id = 0;
    for (int cycle = 0; cycle < 2; ++cycle) {
        addBoth(heap, reference, rng, id, 70000, 100000, false);
        std::sort(reference.begin(), reference.end(), [](const Entry& a, const Entry& b) { return b < a; });
        for (int i = 0; i < 60000; ++i) {
            const Entry got = heap.pop();
            ASSERT_EQ(got.id, reference.back().id) << "cycle " << cycle << " pop " << i;
            reference.pop_back();
        }
        ASSERT_EQ(heap.size(), reference.size());
    }
    std::vector<uint32_t> drained, expected;
    for (size_t i = 0; i < heap.size(); ++i) expected.push_back(heap.entry(i).id);
    heap.drain([&](const Entry& e) { drained.push_back(e.id); });
    EXPECT_EQ(drained, expected);
    EXPECT_TRUE(heap.empty());
    heap.push({5, 1, 0});  // usable again after a drain
    heap.push({3, 2, 0});
    EXPECT_EQ(heap.pop().id, 2u);
    EXPECT_EQ(heap.size(), 1u);
}

TEST(QuadHeap, ADrainedHeapsChunksServeTheHeapItFills)
{
    // A merge drains one heap into another (drain's `into`): the chunks the drain has read serve the
    // other heap's growth. Entries pushed while the drain runs, into chunks that held the drained
    // heap's entries, and more pushed after it, pop in order against the reference.
    std::mt19937_64 rng(5);
    QuadHeap<Entry> from, into;
    std::vector<Entry> ignored, reference;
    uint32_t id = 0;
    addBoth(from, ignored, rng, id, 100000, 1000, false);
    addBoth(into, reference, rng, id, 20000, 1000, false);
    from.drain(
        [&](const Entry& e) {
            if (e.id % 3 == 0) return;  // entries a merge drops (dead) leave chunks over
            into.push(e);
            reference.push_back(e);
        },
        &into);
    EXPECT_TRUE(from.empty());
    addBoth(into, reference, rng, id, 30000, 1000, false);
    into.dropSpares();
    ASSERT_EQ(into.size(), reference.size());
    std::sort(reference.begin(), reference.end(), [](const Entry& a, const Entry& b) { return b < a; });
    for (size_t i = 0; !reference.empty(); ++i) {
        const Entry got = into.pop();
        ASSERT_EQ(got.id, reference.back().id) << "pop " << i;
        reference.pop_back();
    }
    EXPECT_TRUE(into.empty());
}

TEST(QuadHeap, SiblingGroupsStartOnCacheLines)
{
    QuadHeap<Entry> heap;
    for (uint32_t i = 0; i < 20000; ++i) heap.push({i, i, 0});  // several chunks
    // The children 4i+1.. of logical entry i must start a 64-byte line, in every chunk.
    for (size_t i = 0; 4 * i + 1 < heap.size(); ++i)
        ASSERT_EQ(reinterpret_cast<uintptr_t>(&heap.entry(4 * i + 1)) % 64, 0u) << i;
}

} // namespace
} // namespace vdb_isosimp
