// The cut into slabs (pipeline/slabs): whole block layers only, every block in exactly one slab, about
// equal block counts, and nothing but the block list deciding it.
#include "pipeline/slabs.h"

#include <gtest/gtest.h>

#include <random>

using namespace vdb_isosimp;

TEST(Slabs, CutBetweenLayersIntoAboutEqualRuns)
{
    std::mt19937 rng(11);
    std::vector<BlockOrigin> blocks;
    for (int i = 0; i < 20000; ++i)
        blocks.push_back({8 * int32_t(rng() % 40), 8 * int32_t(rng() % 40), 8 * int32_t(rng() % 60)});
    sortBlocks(blocks);
    const std::vector<Slab> slabs = splitSlabs(blocks, kPipelineSlabs);
    ASSERT_EQ(slabs.size(), kPipelineSlabs);
    size_t next = 0;
    for (const Slab& s : slabs) {
        EXPECT_EQ(s.begin, next);
        ASSERT_LT(s.begin, s.end);
        EXPECT_EQ(s.zStart, blocks[s.begin][2]);
        if (s.begin > 0) {
            EXPECT_NE(blocks[s.begin - 1][2], blocks[s.begin][2]) << "a layer cut in two";
        }
        // 60 layers of ~330 blocks into 8: each slab within a layer and a half of an eighth.
        EXPECT_NEAR(double(s.end - s.begin), double(blocks.size()) / kPipelineSlabs, 1.5 * blocks.size() / 60.0);
        next = s.end;
    }
    EXPECT_EQ(next, blocks.size());
    // Fewer layers than slabs: one slab per layer.
    std::vector<BlockOrigin> thin;
    for (int32_t z : {0, 8, 16})
        for (int32_t x = 0; x < 80; x += 8) thin.push_back({x, 0, z});
    const std::vector<Slab> few = splitSlabs(thin, kPipelineSlabs);
    ASSERT_EQ(few.size(), 3u);
    for (size_t i = 0; i < 3; ++i) EXPECT_EQ(few[i].zStart, int32_t(8 * i));
    EXPECT_TRUE(splitSlabs({}, kPipelineSlabs).empty());
}
