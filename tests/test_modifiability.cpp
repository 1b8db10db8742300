// Oracle for the modifiability rule on random sparse grids: at every finalisation all four cells sharing
// the vertex's edge have been extracted, and every vertex is finalised exactly once. Also checks that
// the block list covers every straddling cell of a dense copy (no holes) and that the block order
// is z, y, x.
#include "core/edge_key.h"
#include "core/marching_cubes.h"
#include "core/modifiability.h"
#include "test_grids.h"
#include "vdb/block_order.h"

#include <openvdb/tools/Dense.h>

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <tuple>

using namespace vdb_isosimp;
using Cell = std::tuple<int, int, int>;

namespace {

void runOracle(const vdb_isosimp::testing::GridSpec& spec, double iso)
{
    auto grid = vdb_isosimp::testing::randomSparseGrid(spec);
    Classifier cls;
    cls.iso = iso;
    cls.insideBelow = spec.levelSet;
    const auto blocks = collectBlocks(grid->tree(), cls);
    for (size_t i = 1; i < blocks.size(); ++i) {
        const auto& a = blocks[i - 1];
        const auto& b = blocks[i];
        ASSERT_TRUE(std::make_tuple(a[2], a[1], a[0]) < std::make_tuple(b[2], b[1], b[0])) << "not in z/y/x order";
    }
    auto acc = grid->getConstAccessor();
    auto straddles = [&](int x, int y, int z) {
        int n = 0;
        for (int c = 0; c < 8; ++c) n += cls.inside(acc.getValue(openvdb::Coord(x + (c & 1), y + ((c >> 1) & 1), z + ((c >> 2) & 1))));
        return n != 0 && n != 8;
    };

    std::set<Cell> extracted;
    std::map<EdgeKey, int> finalised;
    for (const auto& b : blocks)
        for (int z = b[2]; z < b[2] + 8; ++z)
            for (int y = b[1]; y < b[1] + 8; ++y)
                for (int x = b[0]; x < b[0] + 8; ++x) {
                    if (!straddles(x, y, z)) continue;
                    ASSERT_TRUE(extracted.insert({x, y, z}).second) << "cell extracted twice";
                    for (int e = 0; e < 12; ++e) {
                        if (!kFinalAfterCell[e]) continue;
                        const int axis = CubeGeometry::edgeAxis(e);
                        const int v0 = cls.inside(acc.getValue(openvdb::Coord(x, y, z)));
                        const int v1 = cls.inside(acc.getValue(openvdb::Coord(x + (axis == 0), y + (axis == 1), z + (axis == 2))));
                        if (v0 == v1) continue;  // no vertex on this edge
                        // All four cells sharing the edge must be done.
                        const int u = (axis + 1) % 3, w = (axis + 2) % 3;
                        for (int du = 0; du < 2; ++du)
                            for (int dw = 0; dw < 2; ++dw) {
                                int c[3] = {x, y, z};
                                c[u] -= du;
                                c[w] -= dw;
                                ASSERT_TRUE(extracted.count({c[0], c[1], c[2]}))
                                    << "vertex finalised before cell (" << c[0] << "," << c[1] << "," << c[2] << ")";
                            }
                        ++finalised[makeEdgeKey(x, y, z, axis)];
                    }
                }

    // Completeness against a dense scan of the bounding box: every straddling cell was extracted, and
    // every crossing edge finalised exactly once.
    openvdb::CoordBBox box;
    grid->tree().evalLeafBoundingBox(box);
    for (auto it = grid->tree().cbeginValueAll(); it; ++it) {
        if (it.isVoxelValue()) continue;
        openvdb::CoordBBox tb;
        it.getBoundingBox(tb);
        if (*it != grid->background()) box.expand(tb);
    }
    box.expand(2);
    size_t straddling = 0, crossingEdges = 0;
    for (int z = box.min().z(); z < box.max().z(); ++z)
        for (int y = box.min().y(); y < box.max().y(); ++y)
            for (int x = box.min().x(); x < box.max().x(); ++x) {
                if (straddles(x, y, z)) {
                    ++straddling;
                    ASSERT_TRUE(extracted.count({x, y, z})) << "missed straddling cell " << x << "," << y << "," << z;
                }
                for (int axis = 0; axis < 3; ++axis) {
                    const bool a = cls.inside(acc.getValue(openvdb::Coord(x, y, z)));
                    const bool b = cls.inside(acc.getValue(openvdb::Coord(x + (axis == 0), y + (axis == 1), z + (axis == 2))));
                    if (a == b) continue;
                    ++crossingEdges;
                    auto f = finalised.find(makeEdgeKey(x, y, z, axis));
                    ASSERT_TRUE(f != finalised.end()) << "vertex never finalised";
                    ASSERT_EQ(f->second, 1) << "vertex finalised more than once";
                }
            }
    EXPECT_EQ(straddling, extracted.size());
    EXPECT_EQ(crossingEdges, finalised.size());
    EXPECT_GT(straddling, 1000u);
}

} // namespace

TEST(Modifiability, TableMarksTheMinCornerEdges)
{
    for (int e = 0; e < 12; ++e) EXPECT_EQ(kFinalAfterCell[e], CubeGeometry::edgeCorner(e, 0) == 0) << e;
}

TEST(Modifiability, BlockRule)
{
    EXPECT_TRUE(finalAfterBlock({0, 0, 0}, {0, 0, 0}));
    EXPECT_TRUE(finalAfterBlock({7, 7, 7}, {0, 0, 0}));
    EXPECT_FALSE(finalAfterBlock({8, 0, 0}, {0, 0, 0}));
    EXPECT_FALSE(finalAfterBlock({-1, 3, 3}, {0, 0, 0}));
}

TEST(Modifiability, EdgeKeyRoundTrip)
{
    for (int32_t v : {kEdgeKeyCoordMin, -1, 0, 1, 12345, kEdgeKeyCoordMax})
        for (int axis = 0; axis < 3; ++axis) {
            const EdgeCoord c = decodeEdgeKey(makeEdgeKey(v, -v / 2, 7, axis));
            EXPECT_EQ(c.x, v);
            EXPECT_EQ(c.y, -v / 2);
            EXPECT_EQ(c.z, 7);
            EXPECT_EQ(c.axis, axis);
        }
}

TEST(Modifiability, OracleOnRandomSparseLevelSets)
{
    for (unsigned seed = 1; seed <= 4; ++seed) {
        vdb_isosimp::testing::GridSpec spec;
        spec.seed = seed;
        spec.bigTile = seed == 2;
        runOracle(spec, 0.0);
    }
}

TEST(Modifiability, OracleOnRandomSparseFog)
{
    for (unsigned seed = 11; seed <= 13; ++seed) {
        vdb_isosimp::testing::GridSpec spec;
        spec.seed = seed;
        spec.levelSet = false;
        runOracle(spec, 0.5);
    }
}
