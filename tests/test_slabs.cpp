// The cut into slabs and the merge tree (pipeline/slabs): every block in exactly one slab, about equal
// block counts, a tree whose shape and rank shares depend on the slab count alone, and the seam rule
// checked against the cells around each edge.
#include "pipeline/slabs.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <map>
#include <random>
#include <set>

using namespace vdb_isosimp;

namespace {

std::vector<BlockOrigin> randomBlocks(unsigned seed, int count, int extent)
{
    std::mt19937 rng(seed);
    std::vector<BlockOrigin> blocks;
    for (int i = 0; i < count; ++i)
        blocks.push_back({8 * int32_t(rng() % extent) - 16, 8 * int32_t(rng() % extent) - 8, 8 * int32_t(rng() % extent)});
    sortBlocks(blocks);
    return blocks;
}

} // namespace

TEST(Slabs, CountGrowsWithTheVolumeUpToALimit)
{
    EXPECT_EQ(slabCount(0, kDefaultBlocksPerSlab), 1u);
    EXPECT_EQ(slabCount(100, kDefaultBlocksPerSlab), 1u);
    EXPECT_EQ(slabCount(2049, 2048), 2u);
    EXPECT_EQ(slabCount(185193, 2048), 91u);  // the 448^3 perf volume: at least 64 pieces of work
    EXPECT_EQ(slabCount(10000000, 2048), kMaxSlabs);
    EXPECT_EQ(slabCount(5, 1), 5u);
}

TEST(Slabs, EqualRunsCoveringEveryBlockOnce)
{
    const std::vector<BlockOrigin> blocks = randomBlocks(11, 20000, 40);
    for (size_t count : {1, 7, 64, 256}) {
        const std::vector<Slab> slabs = splitSlabs(blocks, count);
        ASSERT_EQ(slabs.size(), count);
        size_t next = 0;
        for (const Slab& s : slabs) {
            EXPECT_EQ(s.begin, next);
            ASSERT_LT(s.begin, s.end);
            EXPECT_LE(s.end - s.begin, blocks.size() / count + 1);
            EXPECT_GE(s.end - s.begin, blocks.size() / count);
            next = s.end;
        }
        EXPECT_EQ(next, blocks.size());
    }
    EXPECT_EQ(splitSlabs(std::vector<BlockOrigin>(3, BlockOrigin{0, 0, 0}), 8).size(), 3u);
    EXPECT_TRUE(splitSlabs({}, 8).empty());
}

// Every node of the tree is made exactly once, by the first rank of its share; a rank's own node is the
// highest one it is first in, and it goes to the rank that makes the parent. Checked by walking the
// tree as the ranks do, for every slab count and rank count up to a few dozen.
TEST(Slabs, ParentNodeIsTheNodeWhoseChildrenAreTheGivenOne)
{
    // Against the tree built top-down: every node's children name it as their parent, in any subtree.
    for (size_t slabs : {2, 3, 7, 91, 256}) {
        size_t checked = 0;
        std::vector<std::pair<size_t, size_t>> nodes{{0, slabs}};
        while (!nodes.empty()) {
            const auto [l, r] = nodes.back();
            nodes.pop_back();
            if (r - l < 2) continue;
            const size_t m = mergeSplit(l, r);
            for (const auto& child : {std::make_pair(l, m), std::make_pair(m, r)}) {
                EXPECT_EQ(parentNode(0, slabs, child.first, child.second), std::make_pair(l, r)) << slabs;
                EXPECT_EQ(parentNode(l, r, child.first, child.second), std::make_pair(l, r)) << slabs;
                nodes.push_back(child);
                ++checked;
            }
        }
        EXPECT_EQ(checked, 2 * (slabs - 1)) << slabs;
    }
}

TEST(Slabs, RankSharesMakeEveryNodeOnce)
{
    for (size_t slabs = 1; slabs <= 40; ++slabs)
        for (size_t ranks = 1; ranks <= 9; ++ranks) {
            std::map<std::pair<size_t, size_t>, size_t> maker;  // node -> rank
            std::function<void(size_t, size_t, size_t, size_t)> walk = [&](size_t l, size_t r, size_t a, size_t b) {
                ASSERT_LT(a, b);
                ASSERT_TRUE(maker.emplace(std::make_pair(l, r), a).second);
                if (r - l < 2) return;
                const size_t m = mergeSplit(l, r);
                ASSERT_LT(l, m);
                ASSERT_LT(m, r);
                EXPECT_GE(m - l, r - m) << "the left half is the larger";
                const RankShare s = splitRanks(l, r, a, b);
                if (b - a < 2) {
                    walk(l, m, a, b);
                    walk(m, r, a, b);
                    return;
                }
                EXPECT_EQ(s.leftBegin, a);
                EXPECT_EQ(s.leftEnd, s.rightBegin);
                EXPECT_EQ(s.rightEnd, b);
                walk(l, m, s.leftBegin, s.leftEnd);
                walk(m, r, s.rightBegin, s.rightEnd);
            };
            walk(0, slabs, 0, ranks);
            EXPECT_EQ(maker.size(), 2 * slabs - 1);
            std::set<size_t> working;
            for (size_t rank = 0; rank < ranks; ++rank) {
                const RankNode n = rankNode(slabs, rank, ranks);
                const std::string what = std::to_string(slabs) + " slabs, rank " + std::to_string(rank) + " of " + std::to_string(ranks);
                if (!n.found) {
                    for (const auto& [node, who] : maker) EXPECT_NE(who, rank) << what;
                    continue;
                }
                working.insert(rank);
                EXPECT_EQ(maker.at({n.l, n.r}), rank) << what;
                EXPECT_EQ(n.a, rank) << what;
                if (rank == 0) {
                    EXPECT_EQ(n.l, 0u);
                    EXPECT_EQ(n.r, slabs);
                } else {
                    // Its parent ends where it ends and is made by the rank it sends to.
                    bool parentFound = false;
                    for (const auto& [node, who] : maker)
                        if (node.second == n.r && node.first < n.l && mergeSplit(node.first, node.second) == n.l) {
                            EXPECT_EQ(who, n.parent) << what;
                            EXPECT_LT(n.parent, rank) << what;
                            parentFound = true;
                        }
                    EXPECT_TRUE(parentFound) << what;
                }
            }
            EXPECT_EQ(working.size(), std::min(slabs, ranks)) << slabs << " slabs, " << ranks << " ranks";
            // The slabs each rank extracts itself: consecutive shares that cover every slab once.
            size_t next = 0;
            for (size_t rank = 0; rank < ranks; ++rank) {
                const auto [first, end] = rankSlabs(slabs, rank, ranks);
                if (first == end) continue;
                EXPECT_EQ(first, next) << slabs << " slabs, rank " << rank << " of " << ranks;
                next = end;
            }
            EXPECT_EQ(next, slabs) << slabs << " slabs, " << ranks << " ranks";
        }
}

// Any band height keeps the order monotone (a block never comes after one componentwise above it),
// which the modifiability rule needs; a volume that makes one slab keeps plain z/y/x.
TEST(Slabs, BandedOrderIsMonotone)
{
    const std::vector<BlockOrigin> blocks = randomBlocks(9, 3000, 12);
    EXPECT_EQ(blockOrderFor(blocks, blocks.size()).bandRows, BlockOrder{}.bandRows);
    const BlockOrder banded = blockOrderFor(blocks, 64);
    EXPECT_GE(banded.bandRows, 1);
    EXPECT_LT(banded.bandRows, 12);
    for (const BlockOrder order : {BlockOrder{}, banded, BlockOrder{1}, BlockOrder{3}})
        for (size_t i = 0; i < blocks.size(); ++i)
            for (size_t j = 0; j < blocks.size(); j += 7) {
                const BlockOrigin &a = blocks[i], &b = blocks[j];
                if (a[0] <= b[0] && a[1] <= b[1] && a[2] <= b[2]) {
                    ASSERT_FALSE(order(b, a)) << "band rows " << order.bandRows;
                }
            }
}

// The seam rule against its definition: a vertex on edge (v, axis) is final within blocks [begin, end)
// iff all four cells around the edge lie in blocks of that range.
TEST(Slabs, EdgeWithinMatchesTheCellsAroundTheEdge)
{
  for (const BlockOrder order : {BlockOrder{}, BlockOrder{2}}) {
    std::vector<BlockOrigin> blocks = randomBlocks(5, 600, 6);
    std::sort(blocks.begin(), blocks.end(), order);
    auto indexOf = [&](const BlockOrigin& o) {
        const auto it = std::lower_bound(blocks.begin(), blocks.end(), o, order);
        return it != blocks.end() && *it == o ? long(it - blocks.begin()) : -1L;
    };
    auto blockOf = [](int32_t x, int32_t y, int32_t z) { return BlockOrigin{x & ~7, y & ~7, z & ~7}; };
    std::mt19937 rng(3);
    size_t checked = 0, inside = 0;
    for (int trial = 0; trial < 20000; ++trial) {
        const BlockOrigin& b = blocks[rng() % blocks.size()];
        const int32_t x = b[0] + int32_t(rng() % 8), y = b[1] + int32_t(rng() % 8), z = b[2] + int32_t(rng() % 8);
        const int axis = int(rng() % 3);
        long lo = long(blocks.size()), hi = -1;
        bool allListed = true;
        for (int d = 0; d < 4; ++d) {
            int32_t c[3] = {x, y, z};
            const int u = (axis + 1) % 3, w = (axis + 2) % 3;
            c[u] -= d & 1;
            c[w] -= (d >> 1) & 1;
            const long i = indexOf(blockOf(c[0], c[1], c[2]));
            if (i < 0) allListed = false;
            lo = std::min(lo, i);
            hi = std::max(hi, i);
        }
        if (!allListed) continue;  // no vertex there: its cells would all be in the list
        ++checked;
        const size_t begin = rng() % blocks.size(), end = begin + rng() % (blocks.size() - begin + 1);
        const bool expect = lo >= long(begin) && (end == blocks.size() || hi < long(end));
        inside += expect;
        EXPECT_EQ(edgeWithin(makeEdgeKey(x, y, z, axis), blocks, order, begin, end), expect)
            << x << "," << y << "," << z << " axis " << axis << " blocks [" << begin << ", " << end << ")";
    }
    EXPECT_GT(checked, 5000u);
    EXPECT_GT(inside, 500u);
    EXPECT_LT(inside, checked - 500);
  }
}
