// The decimator's chunked arrays (core/chunked_vector.h): chunks let go of by one array and filled
// again by another.
#include "core/chunked_vector.h"

#include <gtest/gtest.h>

#include <cstdint>

namespace vdb_isosimp {
namespace {

struct Record {
    double x = 0.0;
    uint32_t id = 0;
};

TEST(ChunkedVector, AChunkLetGoIsFilledAgainByTheNextArray)
{
    using Array = ChunkedVector<Record, 4>;  // chunks of 16
    Array from, into;
    Array::Spares spares;
    for (uint32_t i = 0; i < 48; ++i) from.emplace_back() = {1.5, i};
    const Record* firstChunk = &from[0];
    // Reading the first two chunks through lets them go: the first waits as a spare, the second is
    // freed (at most kMax, 1, wait).
    for (size_t i = 0; i < 32; ++i) from.releaseThrough(i, &spares);
    EXPECT_EQ(spares.size(), Array::Spares::kMax);
    EXPECT_EQ(from[40].id, 40u) << "the chunks not read through stay";
    // The next array's first chunk is the spare, its element value-initialised, not the old content.
    Record& first = into.emplace_back(&spares);
    EXPECT_EQ(spares.size(), 0u);
    EXPECT_EQ(&first, firstChunk);
    EXPECT_EQ(first.id, 0u);
    EXPECT_EQ(first.x, 0.0);
    // Without a spare, a fresh chunk.
    for (uint32_t i = 1; i < 20; ++i) into.emplace_back(&spares).id = i;
    EXPECT_EQ(into.size(), 20u);
    EXPECT_EQ(into[19].id, 19u);
    // Spares are room, not content: a copy of them starts empty.
    Array::Spares more;
    from.releaseThrough(47, &more);
    const Array::Spares copy(more);
    EXPECT_EQ(more.size(), 1u);
    EXPECT_EQ(copy.size(), 0u);
}

} // namespace
} // namespace vdb_isosimp
