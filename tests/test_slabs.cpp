// The cut into slabs and the merge tree (pipeline/slabs): every block in exactly one slab, about equal
// block counts, a tree whose shape and rank shares depend on the slab count alone, and the seam rule
// checked against the cells around each edge.
#include "pipeline/slabs.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

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
    EXPECT_EQ(slabCount(185193, 2048), 128u);  // the 448^3 perf volume: at least 64 pieces of work
    EXPECT_EQ(slabCount(10000000, 2048), kMaxSlabs);
    EXPECT_EQ(slabCount(5, 1), 8u);
}

TEST(Slabs, CountSplitsEvenlyAmongAPowerOfTwoOfRanks)
{
    // Every count is a power of two, at least ceil(blocks / per) and under twice it (or kMaxSlabs); then
    // 2^j ranks up to the count each make the same number of slabs.
    for (uint64_t per : {1, 7, 2048}) {
        for (size_t blocks = 1; blocks < 3000 * per; blocks += 1 + blocks / 50) {
            const size_t count = slabCount(blocks, per);
            const uint64_t wanted = std::min<uint64_t>((blocks + per - 1) / per, kMaxSlabs);
            ASSERT_GE(count, wanted) << blocks << " blocks, " << per << " a slab";
            ASSERT_LT(count, std::max<uint64_t>(wanted * 2, 2)) << blocks << " blocks, " << per << " a slab";
            ASSERT_EQ(count & (count - 1), 0u) << count;
            for (size_t ranks = 1; ranks <= count; ranks *= 2) {
                std::vector<size_t> made;
                for (size_t r = 0; r < ranks; ++r) {
                    const auto [first, end] = rankSlabs(count, r, ranks);
                    made.push_back(end - first);
                }
                ASSERT_EQ(*std::min_element(made.begin(), made.end()), *std::max_element(made.begin(), made.end()))
                    << count << " slabs on " << ranks << " ranks";
            }
        }
    }
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

// The merge tree's order is monotone (a block never comes after one componentwise above it), which the
// modifiability rule needs, for listed blocks and any other origin alike; it is a strict total order;
// the arranged list is in it, each block told its place in the z/y/x list it came from; and each slab is
// the run splitSlabs cuts.
TEST(Slabs, TreeOrderIsMonotone)
{
    std::mt19937 rng(5);
    for (size_t slabs : {1, 2, 7, 64}) {
        std::vector<BlockOrigin> blocks = randomBlocks(9, 3000, 12);
        const std::vector<BlockOrigin> listed = blocks;
        ASSERT_TRUE(std::is_sorted(listed.begin(), listed.end(), [](const BlockOrigin& a, const BlockOrigin& b) { return lexBefore(a, b, 2); }));
        PooledVector<uint32_t> place;
        const BlockOrder order = arrangeBlocks(blocks, slabs, &place);
        ASSERT_EQ(blocks.size(), listed.size());
        ASSERT_TRUE(std::is_permutation(blocks.begin(), blocks.end(), listed.begin()));
        ASSERT_EQ(place.size(), blocks.size());
        for (size_t j = 0; j < blocks.size(); ++j) ASSERT_EQ(listed[place[j]], blocks[j]) << slabs << " slabs, block " << j;
        ASSERT_TRUE(std::is_sorted(blocks.begin(), blocks.end(), order)) << slabs << " slabs";
        std::vector<BlockOrigin> points = blocks;
        for (int i = 0; i < 500; ++i)  // origins that are no block, some outside the blocks' box
            points.push_back({8 * int32_t(rng() % 16) - 24, 8 * int32_t(rng() % 16) - 16, 8 * int32_t(rng() % 16) - 8});
        for (size_t i = 0; i < points.size(); ++i)
            for (size_t j = i % 5; j < points.size(); j += 5) {
                const BlockOrigin &a = points[i], &b = points[j];
                ASSERT_FALSE(order(a, a));
                if (a != b) {
                    ASSERT_NE(order(a, b), order(b, a)) << slabs << " slabs";
                }
                if (a[0] <= b[0] && a[1] <= b[1] && a[2] <= b[2]) {
                    ASSERT_FALSE(order(b, a)) << slabs << " slabs";
                }
            }
        const std::vector<Slab> cut = splitSlabs(blocks, slabs);
        for (const Slab& s : cut)  // a slab is swept z, y, x
            ASSERT_TRUE(std::is_sorted(blocks.begin() + long(s.begin), blocks.begin() + long(s.end),
                                       [](const BlockOrigin& a, const BlockOrigin& b) { return lexBefore(a, b, 2); }));
    }
}

// The halves of every node are arranged on threads of their own: the order, the nodes and each block's
// place come out the same on one thread and on several, and the nodes are numbered in pre-order (a left
// child follows its parent, every node but the root is the child of exactly one).
TEST(Slabs, TreeOrderIsTheSameOnAnyNumberOfThreads)
{
    for (size_t slabs : {2, 7, 64, 300}) {
        const std::vector<BlockOrigin> listed = randomBlocks(11, 20000, 40);
        std::vector<BlockOrigin> one = listed, many = listed;
        PooledVector<uint32_t> placeOne, placeMany;
        BlockOrder orderOne, orderMany;
        tbb::task_arena(1).execute([&] { orderOne = arrangeBlocks(one, slabs, &placeOne); });
        tbb::task_arena(4).execute([&] { orderMany = arrangeBlocks(many, slabs, &placeMany); });
        EXPECT_EQ(one, many) << slabs << " slabs";
        EXPECT_EQ(placeOne, placeMany) << slabs << " slabs";
        ASSERT_EQ(orderOne.nodes.size(), 2 * slabs - 1);
        ASSERT_EQ(orderMany.nodes.size(), orderOne.nodes.size());
        std::vector<int> parents(orderOne.nodes.size(), 0);
        for (size_t id = 0; id < orderOne.nodes.size(); ++id) {
            const BlockOrder::Node &a = orderOne.nodes[id], &b = orderMany.nodes[id];
            EXPECT_EQ(a.axis, b.axis);
            EXPECT_EQ(a.boundary, b.boundary);
            EXPECT_EQ(a.left, b.left);
            EXPECT_EQ(a.right, b.right);
            if (a.axis < 0) continue;
            EXPECT_EQ(a.left, id + 1) << slabs << " slabs, node " << id;
            ASSERT_LT(a.right, parents.size());
            ++parents[a.left];
            ++parents[a.right];
        }
        EXPECT_EQ(parents[0], 0);
        for (size_t id = 1; id < parents.size(); ++id) EXPECT_EQ(parents[id], 1) << slabs << " slabs, node " << id;
    }
}

// A rank arranges its own slabs alone (and cuts the nodes above them): those slabs hold the blocks, in
// the order, that the whole arrangement gives them, each told its place in the z/y/x list; every block
// lies among the slabs of the same subtree above them; and slabSide answers as the whole arrangement
// does for listed blocks and other origins, on the rank's slabs and on every node above them.
TEST(Slabs, RankArrangesItsOwnSlabsAsTheWholeOrderDoes)
{
    std::mt19937 rng(17);
    for (size_t slabs : {2, 7, 64, 300}) {
        const std::vector<BlockOrigin> listed = randomBlocks(13, 6000, 24);
        std::vector<BlockOrigin> whole = listed;
        const BlockOrder all = arrangeBlocks(whole, slabs);
        const std::vector<Slab> cut = splitSlabs(whole, slabs);
        std::vector<BlockOrigin> points = listed;
        for (int i = 0; i < 1000; ++i)  // origins that are no block, some outside the blocks' box
            points.push_back({8 * int32_t(rng() % 32) - 24, 8 * int32_t(rng() % 32) - 16, 8 * int32_t(rng() % 32) - 8});
        for (size_t ranks : {2, 3, 16}) {
            for (size_t rank = 0; rank < ranks; ++rank) {
                const auto [l, r] = rankSlabs(slabs, rank, ranks);
                if (l == r) continue;
                std::vector<BlockOrigin> mine = listed;
                PooledVector<uint32_t> place;
                const BlockOrder part = arrangeBlocks(mine, slabs, &place, l, r);
                for (size_t j = 0; j < mine.size(); ++j) ASSERT_EQ(listed[place[j]], mine[j]);
                std::vector<uint32_t> places(place.begin(), place.end());  // each place once: a permutation of the list
                std::sort(places.begin(), places.end());
                for (size_t j = 0; j < places.size(); ++j) ASSERT_EQ(places[j], j);
                for (size_t j = cut[l].begin; j < cut[r - 1].end; ++j)
                    ASSERT_EQ(mine[j], whole[j]) << slabs << " slabs, rank " << rank << " of " << ranks << ", block " << j;
                // The nodes above the rank's slabs and its own ranges, down from the root.
                std::vector<std::pair<size_t, size_t>> ranges{{l, r}};
                for (size_t nl = 0, nr = slabs; nr - nl >= 2 && !(nl == l && nr == r);) {
                    ranges.push_back({nl, nr});
                    const size_t m = mergeSplit(nl, nr);
                    (l < m ? nr : nl) = m;
                }
                for (size_t k = l; k < std::min(r, l + 4); ++k) ranges.push_back({k, k + 1});
                for (const auto& [rl, rr] : ranges) {
                    for (size_t j = cut[rl].begin; j < cut[rr - 1].end; ++j) ASSERT_EQ(part.slabSide(mine[j], rl, rr), 0);
                    for (size_t i = rl % 7; i < points.size(); i += 7)
                        ASSERT_EQ(part.slabSide(points[i], rl, rr), all.slabSide(points[i], rl, rr))
                            << slabs << " slabs, rank " << rank << " of " << ranks << ", slabs [" << rl << ", " << rr << ")";
                }
            }
        }
        // slabSide against the whole order's positions: a listed block lies before, among or after slabs.
        for (size_t i = 0; i < 200; ++i) {
            const size_t l = rng() % slabs, r = l + 1 + rng() % (slabs - l);
            const size_t j = rng() % whole.size();
            const int expect = j < cut[l].begin ? -1 : j < cut[r - 1].end ? 0 : 1;
            ASSERT_EQ(all.slabSide(whole[j], l, r), expect) << slabs << " slabs, block " << j;
        }
    }
}

// What the tree's order is for: the seams between slabs, counted as faces between blocks of different
// slabs on a dense cube of blocks, against slabs cut from the plain z/y/x sweep (sheets a fraction of a
// layer thick), in all and on the way from the root to any slab (the joins one after another).
TEST(Slabs, TreeOrderCutsSmallSeams)
{
    const int n = 24;
    std::vector<BlockOrigin> cube;
    for (int z = 0; z < n; ++z)
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) cube.push_back({8 * x, 8 * y, 8 * z});
    const size_t slabs = 64;
    struct Seams {
        size_t total = 0, path = 0;
    };
    const auto seams = [&](const std::vector<BlockOrigin>& blocks) {
        std::map<BlockOrigin, size_t> slabOf;
        const std::vector<Slab> cut = splitSlabs(blocks, slabs);
        for (size_t s = 0; s < cut.size(); ++s)
            for (size_t i = cut[s].begin; i < cut[s].end; ++i) slabOf[blocks[i]] = s;
        std::map<std::pair<size_t, size_t>, size_t> atNode;  // seam faces each join closes
        Seams out;
        for (const BlockOrigin& b : blocks)
            for (int axis = 0; axis < 3; ++axis) {
                BlockOrigin up = b;
                up[size_t(axis)] += 8;
                const auto it = slabOf.find(up);
                if (it == slabOf.end() || it->second == slabOf[b]) continue;
                ++out.total;
                size_t l = 0, r = slabs, lo = std::min(it->second, slabOf[b]), hi = std::max(it->second, slabOf[b]);
                while (true) {
                    const size_t m = mergeSplit(l, r);
                    if (hi < m) r = m;
                    else if (lo >= m) l = m;
                    else break;
                }
                ++atNode[{l, r}];
            }
        const std::function<size_t(size_t, size_t)> path = [&](size_t l, size_t r) -> size_t {
            if (r - l < 2) return 0;
            const size_t m = mergeSplit(l, r);
            return atNode[{l, r}] + std::max(path(l, m), path(m, r));
        };
        out.path = path(0, slabs);
        return out;
    };
    std::vector<BlockOrigin> tree = cube;
    arrangeBlocks(tree, slabs);
    const Seams sweep = seams(cube), mine = seams(tree);
    // Sheets: every layer boundary is a seam, n - 1 planes, and the top joins close whole planes.
    EXPECT_GE(sweep.total, size_t((n - 1) * n * n));
    EXPECT_LT(mine.total, sweep.total / 2) << mine.total << " against " << sweep.total;
    EXPECT_LT(mine.path, sweep.path / 2) << mine.path << " against " << sweep.path;
    EXPECT_GE(mine.path, size_t(n * n));  // the root's cut is a plane at least
}

// The seam rule against its definition: a vertex on edge (v, axis) is final within slabs [l, r) iff all
// four cells around the edge lie in blocks of those slabs.
TEST(Slabs, EdgeWithinMatchesTheCellsAroundTheEdge)
{
  for (size_t slabs : {1, 2, 9}) {
    std::vector<BlockOrigin> blocks = randomBlocks(5, 600, 6);
    const BlockOrder order = arrangeBlocks(blocks, slabs);
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
        const std::vector<Slab> cut = splitSlabs(blocks, slabs);
        const size_t l = rng() % slabs, r = l + 1 + rng() % (slabs - l);
        const size_t begin = cut[l].begin, end = r < slabs ? cut[r].begin : blocks.size();
        const bool expect = lo >= long(begin) && hi < long(end);
        inside += expect;
        EXPECT_EQ(edgeWithin(makeEdgeKey(x, y, z, axis), order, l, r), expect)
            << x << "," << y << "," << z << " axis " << axis << " slabs [" << l << ", " << r << ")";
    }
    EXPECT_GT(checked, 5000u);
    EXPECT_GT(inside, 500u);
    if (slabs > 1) {
        EXPECT_LT(inside, checked - 500);  // one slab holds every block
    }
  }
}
