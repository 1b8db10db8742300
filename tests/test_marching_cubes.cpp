// The generated case table: every case closes up with its neighbours, and normals point outward.
#include "core/marching_cubes.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <set>

using namespace vdb_isosimp;

TEST(MarchingCubes, EdgeNumbering)
{
    for (int e = 0; e < 12; ++e) {
        const int a = CubeGeometry::edgeCorner(e, 0), b = CubeGeometry::edgeCorner(e, 1);
        EXPECT_EQ(b - a, 1 << CubeGeometry::edgeAxis(e)) << e;
        EXPECT_EQ((a >> CubeGeometry::edgeAxis(e)) & 1, 0) << e;
    }
    // The three min-corner edges start at corner 0.
    for (int e : {0, 4, 8}) EXPECT_EQ(CubeGeometry::edgeCorner(e, 0), 0);
}

TEST(MarchingCubes, TableUsesExactlyTheCrossingEdges)
{
    for (int m = 0; m < 256; ++m) {
        std::set<int> used, crossing;
        for (int e = 0; e < 12; ++e)
            if (((m >> CubeGeometry::edgeCorner(e, 0)) & 1) != ((m >> CubeGeometry::edgeCorner(e, 1)) & 1)) crossing.insert(e);
        const McCase& c = mcTable()[m];
        for (int t = 0; t < c.triangleCount; ++t)
            for (int k = 0; k < 3; ++k) used.insert(c.triangles[t][k]);
        EXPECT_EQ(used, crossing) << "case " << m;
        // Each cell's surface is a union of discs: every crossing edge point is on exactly one fan, so the
        // number of triangles is (points - 2 * loops) and at least points / 3.
        EXPECT_GE(3 * c.triangleCount, int(crossing.size())) << m;
    }
}

TEST(MarchingCubes, SingleCornerNormalPointsAwayFromInside)
{
    // Only corner 0 inside: the triangle's normal must point toward +x+y+z (away from the inside).
    BlockSamples s;
    s.values.fill(1.0);
    s.at(0, 0, 0) = -1.0;
    Classifier c;  // level set, iso 0
    BlockMesh m;
    extractBlock(s, c, Affine{}, false, m);
    ASSERT_EQ(m.triangles.size(), 1u);
    const auto& t = m.triangles[0];
    std::array<double, 3> p[3] = {m.positions[t[0]], m.positions[t[1]], m.positions[t[2]]};
    const double ux = p[1][0] - p[0][0], uy = p[1][1] - p[0][1], uz = p[1][2] - p[0][2];
    const double vx = p[2][0] - p[0][0], vy = p[2][1] - p[0][1], vz = p[2][2] - p[0][2];
    const double n[3] = {uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx};
    EXPECT_GT(n[0], 0);
    EXPECT_GT(n[1], 0);
    EXPECT_GT(n[2], 0);
}

// Random sign patterns on one 8^3 block with an outside border: the welded surface must be closed and
// consistently oriented, i.e. every directed edge appears once and its reverse once. This exercises all
// ambiguous face configurations against each other.
TEST(MarchingCubes, RandomBlocksAreClosedAndOriented)
{
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int trial = 0; trial < 200; ++trial) {
        BlockSamples s;
        for (int z = 0; z < 9; ++z)
            for (int y = 0; y < 9; ++y)
                for (int x = 0; x < 9; ++x) {
                    const bool border = x == 0 || y == 0 || z == 0 || x == 8 || y == 8 || z == 8;
                    s.at(x, y, z) = border ? 1.0 : (trial % 2 ? u(rng) : (u(rng) < 0 ? -1.0 : 0.0));
                }
        BlockMesh m;
        extractBlock(s, Classifier{}, Affine{}, false, m);
        std::map<std::pair<uint32_t, uint32_t>, int> directed;
        for (const auto& t : m.triangles)
            for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
        for (const auto& [e, n] : directed) {
            ASSERT_EQ(n, 1) << "trial " << trial << ": edge used twice in one direction";
            auto r = directed.find({e.second, e.first});
            ASSERT_TRUE(r != directed.end()) << "trial " << trial << ": boundary edge";
        }
    }
}

TEST(MarchingCubes, CountMatchesExtraction)
{
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    BlockSamples s;
    for (double& v : s.values) v = u(rng);
    BlockMesh m;
    extractBlock(s, Classifier{}, Affine{}, false, m);
    EXPECT_EQ(countBlockTriangles(s, Classifier{}), m.triangles.size());
    EXPECT_GT(m.triangles.size(), 500u);
}

// blockCases classifies each sample once and gathers a cell's eight corners from those bits; here each
// cell's case is rebuilt from its own corners (bit k: corner (k & 1, k >> 1 & 1, k >> 2 & 1)), for both
// kinds of grid and with samples exactly at the iso-value.
TEST(MarchingCubes, BlockCasesGatherEachCellsCorners)
{
    std::mt19937 rng(11);
    std::uniform_int_distribution<int> level(-2, 2);
    BlockSamples s;
    for (double& v : s.values) v = 0.25 * level(rng);
    for (const Classifier c : {Classifier{0.0, true}, Classifier{0.25, false}}) {
        const std::array<uint8_t, 512> cases = blockCases(s, c);
        for (int z = 0; z < 8; ++z)
            for (int y = 0; y < 8; ++y)
                for (int x = 0; x < 8; ++x) {
                    int mask = 0;
                    for (int k = 0; k < 8; ++k)
                        if (c.inside(s.at(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2 & 1)))) mask |= 1 << k;
                    ASSERT_EQ(cases[size_t((z * 8 + y) * 8 + x)], mask) << "cell " << x << " " << y << " " << z;
                }
    }
}
