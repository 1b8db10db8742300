// The decimator on hand-made meshes: what a pass tries and what it may not do.
#include "core/decimator.h"
#include "core/edge_key.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <random>
#include <vector>

namespace vdb_isosimp {
namespace {

// `count` closed unit tetrahedra side by side, every vertex final: the tiny components noisy CT data
// is full of. No collapse is legal on them (it would fold the tetrahedron into a doubled triangle).
BlockMesh tetrahedra(int count)
{
    BlockMesh b;
    for (int i = 0; i < count; ++i) {
        const double x = 10.0 * i;
        const uint32_t base = uint32_t(b.keys.size());
        const std::array<double, 3> corners[4] = {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0}, {x, 0, 1}};
        for (int k = 0; k < 4; ++k) {
            b.keys.push_back(makeEdgeKey(10 * i, k, 0, 0));
            b.positions.push_back(corners[k]);
            b.finalAfterBlock.push_back(1);
        }
        for (const auto& t : {std::array<uint32_t, 3>{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}})
            b.triangles.push_back({base + t[0], base + t[1], base + t[2]});
    }
    return b;
}

TEST(Decimator, ClosedTetrahedraAreRefusedOnceNotAtEveryPass)
{
    Decimator d;
    d.addBlock(tetrahedra(50));
    EXPECT_EQ(d.faceCount(), 200u);
    EXPECT_EQ(d.decimateTo(0), 0u);
    EXPECT_EQ(d.faceCount(), 200u);
    // Each of the 6 edges of each tetrahedron was tried once and refused.
    EXPECT_EQ(d.collapseAttempts(), 300u);
    // Later passes (one per batch in the pipeline) retry a refused edge only once the faces around it
    // have changed; nothing changes here, so nothing is tried again.
    for (int pass = 0; pass < 5; ++pass) EXPECT_EQ(d.decimateTo(0), 0u);
    EXPECT_EQ(d.collapseAttempts(), 300u);
    EXPECT_EQ(d.faceCount(), 200u);
    // A full requeue (the final pass does one) tries them all again.
    d.requeueAll();
    EXPECT_EQ(d.decimateTo(0), 0u);
    EXPECT_EQ(d.collapseAttempts(), 600u);
}

TEST(Decimator, OctahedronShrinksToATetrahedronAndStopsThere)
{
    // A closed octahedron: collapses are legal until the tetrahedron, the smallest closed surface.
    BlockMesh b;
    const std::array<double, 3> p[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int k = 0; k < 6; ++k) {
        b.keys.push_back(makeEdgeKey(k, 0, 0, 0));
        b.positions.push_back(p[k]);
        b.finalAfterBlock.push_back(1);
    }
    // +x +y +z ... outward winding.
    b.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    Decimator d;
    d.addBlock(b);
    EXPECT_EQ(d.faceCount(), 8u);
    d.decimateTo(0);
    // Refused edges come back in later passes once their rings changed; a full requeue settles it.
    for (int pass = 0; pass < 4; ++pass) d.decimateTo(0);
    d.requeueAll();
    d.decimateTo(0);
    EXPECT_EQ(d.faceCount(), 4u);
    EXPECT_EQ(d.vertexCount(), 4u);
    const Mesh m = d.mesh();
    EXPECT_EQ(m.triangles.size(), 4u);
}

// A closed octahedron around `centre`, every vertex final; keys start at `firstKey`.
BlockMesh octahedron(std::array<double, 3> centre, int32_t firstKey)
{
    BlockMesh b;
    const std::array<double, 3> p[6] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int k = 0; k < 6; ++k) {
        b.keys.push_back(makeEdgeKey(firstKey + k, 0, 0, 0));
        b.positions.push_back({centre[0] + p[k][0], centre[1] + p[k][1], centre[2] + p[k][2]});
        b.finalAfterBlock.push_back(1);
    }
    b.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    return b;
}

TEST(Decimator, QueuedPairsWhoseSlotWentToANewVertexAreNeverCollapsed)
{
    // One collapse on the first octahedron leaves queue entries naming the dead end. The next block's
    // first vertex takes the dead end's slot, so those entries now pair two live, final vertices that
    // share no face: the queue re-evaluates them without a ring walk, and collapse() must refuse them.
    Decimator d;
    d.addBlock(octahedron({0, 0, 0}, 0));
    EXPECT_EQ(d.decimateTo(6), 1u);
    d.addBlock(octahedron({100, 0, 0}, 100));
    for (int pass = 0; pass < 4; ++pass) d.decimateTo(0);
    d.requeueAll();
    d.decimateTo(0);
    // Each octahedron became a tetrahedron on its own: no face joins the two.
    const Mesh m = d.mesh();
    ASSERT_EQ(m.triangles.size(), 8u);
    size_t nearFirst = 0;
    for (const auto& t : m.triangles) {
        const bool a = m.points[t[0]][0] < 50, b = m.points[t[1]][0] < 50, c = m.points[t[2]][0] < 50;
        EXPECT_TRUE(a == b && b == c) << "a face joins the two octahedra";
        nearFirst += a;
    }
    EXPECT_EQ(nearFirst, 4u);
}

} // namespace
} // namespace vdb_isosimp
