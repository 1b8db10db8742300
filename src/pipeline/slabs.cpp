#include "pipeline/slabs.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include <tbb/parallel_invoke.h>

namespace vdb_isosimp {

size_t slabCount(size_t blocks, uint64_t blocksPerSlab)
{
    const uint64_t per = std::max<uint64_t>(1, blocksPerSlab);
    const uint64_t wanted = std::clamp<uint64_t>((blocks + per - 1) / per, 1, kMaxSlabs);
    uint64_t count = 1;
    while (count < wanted) count *= 2;
    return size_t(std::min<uint64_t>(count, kMaxSlabs));
}

std::vector<Slab> splitSlabs(const std::vector<BlockOrigin>& blocks, size_t count)
{
    std::vector<Slab> slabs;
    const size_t n = std::min(count, blocks.size());
    for (size_t s = 0; s < n; ++s) slabs.push_back({blocks.size() * s / n, blocks.size() * (s + 1) / n});
    return slabs;
}

std::pair<size_t, size_t> parentNode(size_t l, size_t r, size_t nl, size_t nr)
{
    // Walked down from [l, r) into the child that holds [nl, nr), until that child is [nl, nr).
    size_t m = mergeSplit(l, r);
    while (!((l == nl && m == nr) || (m == nl && r == nr))) {
        if (nr <= m) r = m;
        else l = m;
        m = mergeSplit(l, r);
    }
    return {l, r};
}

RankShare splitRanks(size_t l, size_t r, size_t a, size_t b)
{
    const size_t m = mergeSplit(l, r);
    const size_t ranks = b - a;
    if (ranks < 2) return {a, b, a, b};
    const double share = double(ranks) * double(m - l) / double(r - l);
    const size_t left = std::clamp<size_t>(size_t(std::llround(share)), 1, ranks - 1);
    return {a, a + left, a + left, b};
}

RankNode rankNode(size_t slabs, size_t rank, size_t ranks)
{
    size_t l = 0, r = slabs, a = 0, b = ranks, parent = 0;
    while (true) {
        if (a == rank) return {true, l, r, a, b, parent};
        if (r - l < 2 || b - a < 2) return {};  // the node's slab went to rank a; nothing left here
        const size_t m = mergeSplit(l, r);
        const RankShare s = splitRanks(l, r, a, b);
        if (rank < s.rightBegin) {
            r = m;
            b = s.leftEnd;
        } else {
            parent = a;
            l = m;
            a = s.rightBegin;
        }
    }
}

std::pair<size_t, size_t> rankSlabs(size_t slabs, size_t rank, size_t ranks)
{
    const RankNode n = rankNode(slabs, rank, ranks);
    if (!n.found) return {0, 0};
    size_t l = n.l, r = n.r, a = n.a, b = n.b;
    while (b - a >= 2 && r - l >= 2) {  // the left child stays with this rank (rankSubtree)
        b = splitRanks(l, r, a, b).leftEnd;
        r = mergeSplit(l, r);
    }
    return {l, r};
}

EdgeBlocks edgeBlocks(EdgeKey key)
{
    // The cells around an edge from voxel v along axis a are v - {0,1} e_b - {0,1} e_c: the one at v
    // comes last in z/y/x order, the one at v - e_b - e_c first (modifiability.h).
    const EdgeCoord e = decodeEdgeKey(key);
    const int32_t v[3] = {e.x, e.y, e.z};
    int32_t lo[3] = {e.x, e.y, e.z};
    for (int k = 0; k < 3; ++k)
        if (k != e.axis) lo[k] -= 1;
    auto block = [](int32_t c) { return c & ~int32_t(7); };  // rounds down, also below zero
    return {{block(lo[0]), block(lo[1]), block(lo[2])}, {block(v[0]), block(v[1]), block(v[2])}};
}

bool edgeWithin(EdgeKey key, const BlockOrder& order, size_t l, size_t r)
{
    // The order is monotone: the cells' first and last blocks bound the others.
    const EdgeBlocks eb = edgeBlocks(key);
    return order.slabSide(eb.first, l, r) >= 0 && order.slabSide(eb.last, l, r) <= 0;
}

namespace {

// A block on its way through arrangeBlocks: its place in the z/y/x order it came in, and a key that
// orders blocks as lexBefore on the axis of the node it is in does (one integer compare instead of up to three).
struct Placed {
    uint64_t key;
    BlockOrigin origin;
    uint32_t place;
};

// lexBefore(a, b, axis) is lexKey(a, axis) < lexKey(b, axis): the axis, then the others in z, y, x
// order, 21 bits each (block origins lie within the vertex keys' range of +-2^19, edge_key.h).
uint64_t lexKey(const BlockOrigin& b, int axis)
{
    const int first = axis == 2 ? 1 : 2, second = axis == 0 ? 1 : 0;
    const auto bits = [](int32_t v) { return uint64_t(uint32_t(v + (1 << 20)) & 0x1FFFFF); };
    return bits(b[size_t(axis)]) << 42 | bits(b[size_t(first)]) << 21 | bits(b[size_t(second)]);
}

} // namespace

BlockOrder arrangeBlocks(std::vector<BlockOrigin>& blocks, size_t slabs, PooledVector<uint32_t>* sweepPlace,
                         size_t ownFirst, size_t ownEnd)
{
    BlockOrder order;
    const size_t n = blocks.size();
    // Tens of megabytes for a large volume, written once: huge pages spare a page fault per 4 KiB.
    PooledVector<Placed> placed(n);
    for (size_t i = 0; i < n; ++i) placed[i] = {0, blocks[i], uint32_t(i)};
    const auto at = [&](size_t s) { return placed.begin() + std::ptrdiff_t(n * s / slabs); };  // splitSlabs's cut
    const auto byKey = [](const Placed& a, const Placed& b) { return a.key < b.key; };
    const auto keyOn = [](auto first, auto last, int axis) {
        for (auto it = first; it != last; ++it) it->key = lexKey(it->origin, axis);
    };
    // Nodes are numbered in pre-order, so a subtree's numbers follow from its slab range alone: the two
    // halves of every node are arranged at once, on as many threads as the run has (the millions of
    // blocks of a large volume otherwise sort on one while every rank waits for its cut).
    const std::function<void(size_t, size_t, uint32_t)> build = [&](size_t l, size_t r, uint32_t id) {
        if (r <= ownFirst || l >= ownEnd) return;  // another rank's subtree
        const auto first = at(l), last = at(r);
        if (r - l < 2) {
            keyOn(first, last, 2);
            std::sort(first, last, byKey);
            return;
        }
        BlockOrigin lo = first->origin, hi = first->origin;
        for (auto it = first; it != last; ++it)
            for (int k = 0; k < 3; ++k) {
                lo[size_t(k)] = std::min(lo[size_t(k)], it->origin[size_t(k)]);
                hi[size_t(k)] = std::max(hi[size_t(k)], it->origin[size_t(k)]);
            }
        int axis = 2;  // the longest extent; z, then y, then x on ties
        for (int k = 1; k >= 0; --k)
            if (hi[size_t(k)] - lo[size_t(k)] > hi[size_t(axis)] - lo[size_t(axis)]) axis = k;
        const size_t m = mergeSplit(l, r);
        keyOn(first, last, axis);
        std::nth_element(first, at(m), last, byKey);
        const uint32_t left = id + 1, right = id + uint32_t(2 * (m - l));  // the left subtree has 2 (m - l) - 1 nodes
        order.nodes[id] = {axis, at(m)->origin, left, right};
        tbb::parallel_invoke([&] { build(l, m, left); }, [&] { build(m, r, right); });
    };
    if (slabs >= 2 && n >= 2) {
        order.nodes.resize(2 * slabs - 1);
        build(0, slabs, 0);
    }
    if (sweepPlace) sweepPlace->resize(n);
    for (size_t j = 0; j < n; ++j) {
        blocks[j] = placed[j].origin;
        if (sweepPlace) (*sweepPlace)[j] = placed[j].place;
    }
    return order;
}

} // namespace vdb_isosimp
