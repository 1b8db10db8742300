// The block list (vdb/block_order): sorted by z, y, x without duplicates, covering every straddling
// cell of random sparse grids with leaves and tiles of every size, and the tile-shell count the memory
// estimate uses.
#include "test_grids.h"
#include "vdb/block_order.h"

#include <openvdb/tools/Dense.h>

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <set>

using namespace vdb_isosimp;

// Blocks packed in a small box (sorted through a bit per place of it) and spread over a box far
// larger than the list (sorted by comparison), against a set ordered by (z, y, x).
TEST(BlockOrder, SortsByZThenYThenXWithoutDuplicates)
{
    for (const uint32_t places : {9u, 5u, 1u << 20}) {
        std::mt19937 rng(3);
        std::vector<BlockOrigin> blocks;
        for (int i = 0; i < 5000; ++i) {
            const auto at = [&] { return 8 * int32_t(rng() % places) - 8 * int32_t(places / 2); };
            blocks.push_back({at(), at(), at()});
        }
        std::set<std::array<int32_t, 3>> zyx;
        for (const auto& b : blocks) zyx.insert({b[2], b[1], b[0]});
        sortBlocks(blocks);
        ASSERT_EQ(blocks.size(), zyx.size()) << places << " places a side";
        size_t i = 0;
        for (const auto& k : zyx) {
            EXPECT_EQ(blocks[i], (BlockOrigin{k[2], k[1], k[0]})) << i << ", " << places << " places a side";
            ++i;
        }
    }
}

// The blocks that sample a leaf (samplingBlock) are exactly those whose sampled leaves (sampledLeaf)
// include it, found by trying every block around the leaf, also below zero.
TEST(BlockOrder, SamplingBlocksAreTheBlocksWhoseSamplesReadTheLeaf)
{
    for (const BlockOrigin leaf : {BlockOrigin{0, 0, 0}, BlockOrigin{-8, 16, -24}, BlockOrigin{40, -8, 8}}) {
        std::set<BlockOrigin> expected, found;
        for (int x = -24; x <= 24; x += 8)
            for (int y = -24; y <= 24; y += 8)
                for (int z = -24; z <= 24; z += 8) {
                    const BlockOrigin b{leaf[0] + x, leaf[1] + y, leaf[2] + z};
                    for (int d = 0; d < 8; ++d)
                        if (sampledLeaf(b, d) == leaf) expected.insert(b);
                }
        for (int d = 0; d < 8; ++d) {
            found.insert(samplingBlock(leaf, d));
            EXPECT_EQ(sampledLeaf(samplingBlock(leaf, d), d), leaf) << d;
        }
        EXPECT_EQ(found, expected);
        EXPECT_EQ(samplingBlock(leaf, 0), leaf);
    }
}

// Every cell whose corners lie on both sides of the iso-value is in a listed block, found by a dense
// scan of the grid's values (the block of a cell is its corner rounded down to a multiple of 8).
TEST(BlockOrder, CoversEveryStraddlingCell)
{
    for (unsigned seed = 1; seed <= 6; ++seed) {
        vdb_isosimp::testing::GridSpec spec;
        spec.seed = seed;
        spec.levelSet = seed % 2;
        spec.bigTile = seed % 3 == 0;
        const auto grid = vdb_isosimp::testing::randomSparseGrid(spec);
        Classifier c;
        c.insideBelow = spec.levelSet;
        c.iso = spec.levelSet ? 0.0 : 0.5;
        const std::vector<BlockOrigin> blocks = collectBlocks(grid->tree(), c);
        const std::set<BlockOrigin> listed(blocks.begin(), blocks.end());
        EXPECT_EQ(listed.size(), blocks.size()) << "duplicates, seed " << seed;
        std::vector<BlockOrigin> oneThread;  // the leaves divide among threads: the list does not change
        tbb::task_arena(1).execute([&] { oneThread = collectBlocks(grid->tree(), c); });
        EXPECT_EQ(oneThread, blocks) << "seed " << seed;
        // A distributed run's ranks each list a part and merge the parts: the same list, also where a
        // part holds no leaf (more parts than leaves) and where tiles' faces fall to several parts.
        for (size_t parts : {2u, 3u, 7u, 64u}) {
            std::vector<BlockOrigin> merged;
            std::vector<size_t> ends;
            for (size_t part = 0; part < parts; ++part) {
                const std::vector<BlockOrigin> mine = collectBlocks(grid->tree(), c, part, parts);
                EXPECT_TRUE(std::is_sorted(mine.begin(), mine.end(), [](const BlockOrigin& a, const BlockOrigin& b) {
                    return lexBefore(a, b, 2);
                })) << "seed " << seed << ", part " << part << " of " << parts;
                if (!spec.bigTile) {  // the leaves divide (one big tile's faces fall to one part)
                    EXPECT_LT(mine.size(), blocks.size() * 3 / 4 + 64) << "seed " << seed << ", part " << part << " of " << parts;
                }
                merged.insert(merged.end(), mine.begin(), mine.end());
                ends.push_back(merged.size());
            }
            mergeBlockRuns(merged, ends);
            EXPECT_EQ(merged, blocks) << "seed " << seed << ", " << parts << " parts";
        }

        openvdb::CoordBBox box = grid->evalActiveVoxelBoundingBox();
        box.expand(9);
        openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box);
        openvdb::tools::copyToDense(*grid, dense);
        size_t straddling = 0, missing = 0;
        const openvdb::Coord lo = box.min(), hi = box.max();
        for (int z = lo.z(); z < hi.z(); ++z)
            for (int y = lo.y(); y < hi.y(); ++y)
                for (int x = lo.x(); x < hi.x(); ++x) {
                    bool in = false, out = false;
                    for (int d = 0; d < 8; ++d) {
                        const bool i = c.inside(dense.getValue(openvdb::Coord(x + (d & 1), y + ((d >> 1) & 1), z + ((d >> 2) & 1))));
                        (i ? in : out) = true;
                    }
                    if (!(in && out)) continue;
                    ++straddling;
                    const auto down = [](int v) { return v >= 0 ? v / 8 * 8 : -((-v + 7) / 8) * 8; };
                    if (!listed.count({down(x), down(y), down(z)})) ++missing;
                }
        EXPECT_GT(straddling, 0u) << "seed " << seed;
        EXPECT_EQ(missing, 0u) << "seed " << seed << ": straddling cells outside every listed block";
    }
}

// Sorted runs merge into one sorted list without duplicates, whatever their number, overlaps and empty
// runs: the same list as sorting every run's blocks together.
TEST(BlockOrder, RunsMergeIntoOneList)
{
    // A packed box (merged through a bit per place) and the same blocks spread far apart (merged by
    // comparison).
    for (const int32_t spread : {1, 1 << 16})
    for (size_t runs : {1u, 2u, 5u, 8u, 13u}) {
        std::vector<BlockOrigin> all;
        for (int z = 0; z < 40; z += 8)
            for (int y = -16; y < 24; y += 8)
                for (int x = -8; x < 32; x += 8) all.push_back({x * spread, y * spread, z * spread});
        std::set<std::array<int32_t, 3>> zyx;
        std::vector<BlockOrigin> blocks;
        std::vector<size_t> ends;
        for (size_t r = 0; r < runs; ++r) {
            // Every block whose place is r modulo the run count, and every seventh of the others; run 2 empty.
            for (size_t i = 0; i < all.size() && r != 2; ++i)
                if (i % runs == r || (i + r) % 7 == 0) blocks.push_back(all[i]);
            ends.push_back(blocks.size());
        }
        for (const auto& b : blocks) zyx.insert({b[2], b[1], b[0]});
        std::vector<BlockOrigin> expected;
        for (const auto& k : zyx) expected.push_back({k[2], k[1], k[0]});
        if (runs > 1) {
            ASSERT_LT(expected.size(), blocks.size()) << runs << " runs: no block is listed twice";
        }
        mergeBlockRuns(blocks, ends);
        EXPECT_EQ(blocks, expected) << runs << " runs, spread " << spread;
    }
}

// Listing the blocks reads the topology only: a grid read with delayed loading keeps every leaf's
// voxels on disk (probing through a value accessor would load each leaf it caches).
TEST(BlockOrder, ListingLoadsNoLeaf)
{
    vdb_isosimp::testing::GridSpec spec;
    spec.seed = 4;
    spec.levelSet = true;
    const auto grid = vdb_isosimp::testing::randomSparseGrid(spec);
    const std::string path = ::testing::TempDir() + "block_order_delayed.vdb";
    openvdb::io::File(path).write({grid});
    openvdb::io::File file(path);
    file.setCopyMaxBytes(0);
    file.open(/*delayLoad=*/true);
    const auto read = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(grid->getName()));
    ASSERT_TRUE(read);
    Classifier c;
    c.insideBelow = true;
    c.iso = 0.0;
    const std::vector<BlockOrigin> blocks = collectBlocks(read->tree(), c);
    EXPECT_EQ(blocks, collectBlocks(grid->tree(), c));
    size_t leaves = 0, loaded = 0;
    for (auto leaf = read->tree().cbeginLeaf(); leaf; ++leaf, ++leaves) loaded += !leaf->buffer().isOutOfCore();
    EXPECT_GT(leaves, 0u);
    EXPECT_EQ(loaded, 0u) << "of " << leaves << " leaves";
    std::remove(path.c_str());
}

// A tile's faces: one shell of blocks each, counted once where two tiles of one size meet.
TEST(BlockOrder, TileShellsAreCountedBeforeTheyAreListed)
{
    Classifier c;
    c.insideBelow = false;
    c.iso = 0.5;
    const auto grid = openvdb::FloatGrid::create(0.0f);
    grid->tree().addTile(2, openvdb::Coord(0), 1.0f, true);  // 128^3 beside inactive 128^3 background tiles
    EXPECT_EQ(countTileShellBlocks(grid->tree(), c), 6u * 17 * 17);
    const std::vector<BlockOrigin> blocks = collectBlocks(grid->tree(), c);
    EXPECT_LE(blocks.size(), 6u * 17 * 17);
    for (const BlockOrigin& b : blocks) {
        bool onShell = false;
        for (int a = 0; a < 3; ++a) onShell |= b[a] == -8 || b[a] == 120;
        EXPECT_TRUE(onShell) << b[0] << " " << b[1] << " " << b[2];
    }
    // Two tiles of one size side by side: inside and outside, their shared face is counted once (6
    // faces in all); both inside, it is no surface (10 faces).
    for (float second : {0.0f, 1.0f}) {
        const auto two = openvdb::FloatGrid::create(0.0f);
        two->tree().addTile(2, openvdb::Coord(0), 1.0f, true);
        two->tree().addTile(2, openvdb::Coord(128, 0, 0), second, true);
        EXPECT_EQ(countTileShellBlocks(two->tree(), c), (second > 0.5f ? 10u : 6u) * 17 * 17) << second;
    }
}
