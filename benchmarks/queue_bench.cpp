// The decimator's queue (core/radix_queue.h) and its heap part (core/quad_heap.h, the whole queue
// before) against std::priority_queue, in the same run: a queue of N entries, then N pops each followed
// by a push at a random higher cost, anywhere in the queue's range (as in a pass: a stale entry comes
// back at its new cost, a collapse queues its ring's edges). Best of three alternating runs per size;
// the large sizes are the queues of a merge near the tree's root and of a final pass.
// Usage: queue_bench [SIZE...]   (default: 65536 1048576 4194304)
#include "core/quad_heap.h"
#include "core/radix_queue.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <queue>
#include <random>
#include <vector>

namespace {

struct Entry {
    uint64_t key;
    uint32_t b, stamp;  // 16 bytes, like the decimator's entries (QuadHeap requires it)
    uint32_t costBits() const { return uint32_t(key >> 32); }  // RadixQueue's key: the order's first part
    bool operator<(const Entry& o) const { return key != o.key ? key < o.key : b < o.b; }
    bool operator>(const Entry& o) const { return o < *this; }
};

template <typename Queue, typename Push, typename Pop>
double run(size_t n, Queue& q, Push push, Pop pop, uint64_t& checksum)
{
    std::mt19937_64 rng(7);
    for (size_t i = 0; i < n; ++i) push(q, Entry{rng() >> 1, uint32_t(i), 0});
    const auto start = std::chrono::steady_clock::now();
    for (size_t i = 0; i < n; ++i) {
        Entry e = pop(q);
        checksum += e.b;
        e.key += rng() >> 2;
        push(q, e);
    }
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

} // namespace

int main(int argc, char** argv)
{
    std::vector<size_t> sizes;
    for (int i = 1; i < argc; ++i) sizes.push_back(std::strtoull(argv[i], nullptr, 10));
    if (sizes.empty()) sizes = {65536, 1048576, 4194304};
    std::printf("%10s %16s %14s %14s %14s %14s\n", "entries", "RadixQueue ns/op", "QuadHeap ns/op", "std ns/op",
                "Radix / Quad", "Quad / std");
    for (size_t n : sizes) {
        double radix = 1e300, quad = 1e300, theirs = 1e300;
        uint64_t sumRadix = 0, sumQuad = 0, sumTheirs = 0;
        const auto push = [](auto& h, const Entry& e) { h.push(e); };
        const auto pop = [](auto& h) { return h.pop(); };
        for (int round = 0; round < 3; ++round) {
            {
                vdb_isosimp::RadixQueue<Entry> q;
                radix = std::min(radix, run(n, q, push, pop, sumRadix));
            }
            {
                vdb_isosimp::QuadHeap<Entry> q;
                quad = std::min(quad, run(n, q, push, pop, sumQuad));
            }
            {
                std::priority_queue<Entry, std::vector<Entry>, std::greater<Entry>> q;
                theirs = std::min(theirs, run(n, q, push,
                                              [](auto& h) {
                                                  const Entry e = h.top();
                                                  h.pop();
                                                  return e;
                                              },
                                              sumTheirs));
            }
        }
        if (sumRadix != sumTheirs || sumQuad != sumTheirs) {
            std::fprintf(stderr, "queue_bench: the queues popped different entries at %zu\n", n);
            return 1;
        }
        std::printf("%10zu %16.1f %14.1f %14.1f %14.2f %14.2f\n", n, 1e9 * radix / double(n), 1e9 * quad / double(n),
                    1e9 * theirs / double(n), radix / quad, quad / theirs);
    }
    return 0;
}
