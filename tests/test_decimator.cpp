// The decimator on hand-made meshes: what a pass tries and what it may not do.
#include "core/decimator.h"
#include "core/edge_key.h"
#include "core/piece_bytes.h"
#include "surface_checks.h"
#include "test_grids.h"

#include <gtest/gtest.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
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
    EXPECT_EQ(d.work().pops, 300u);
    EXPECT_EQ(d.work().collapses, 0u);
    // Later passes (one per batch in the pipeline) retry a refused edge only once the faces around it
    // have changed; nothing changes here, so nothing is tried again.
    for (int pass = 0; pass < 5; ++pass) EXPECT_EQ(d.decimateTo(0), 0u);
    EXPECT_EQ(d.collapseAttempts(), 300u);
    EXPECT_EQ(d.faceCount(), 200u);
    // A full requeue tries them all again.
    d.requeueAll();
    EXPECT_EQ(d.decimateTo(0), 0u);
    EXPECT_EQ(d.collapseAttempts(), 600u);
    EXPECT_EQ(d.work().pops, 600u);
}

TEST(Decimator, PruneRemovesComponentsBelowAnAreaAndDropKeepsTheLargest)
{
    // Five tetrahedra of area 2.37; the first scaled up 10 times (area 237).
    BlockMesh b = tetrahedra(5);
    for (int k = 1; k < 4; ++k)
        for (double& c : b.positions[size_t(k)]) c *= 10.0;
    Decimator prune;
    prune.addBlock(b);
    EXPECT_EQ(prune.pruneComponents(2.0), 0u);
    EXPECT_EQ(prune.pruneComponents(100.0), 4u);
    EXPECT_EQ(prune.faceCount(), 4u);
    EXPECT_EQ(prune.vertexCount(), 4u);
    EXPECT_EQ(prune.mesh().points[1][0], 10.0f);  // the big one is the one kept
    // The same walk serves the face-target clean-up, which never removes the largest component.
    Decimator drop;
    drop.addBlock(b);
    EXPECT_EQ(drop.dropSmallComponents(0), 4u);
    EXPECT_EQ(drop.faceCount(), 4u);
    EXPECT_EQ(drop.mesh().points[1][0], 10.0f);
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

TEST(Decimator, ZeroWidthNeckOfASmallTorusOpens)
{
    // A 9-vertex torus (what a small handle of integer CT data, iso-value on an integer, shrank to):
    // vertices 1 and 2 lie a rounding error apart on a voxel corner at the iso-value, so the two faces
    // on edge 1-2 have no area. The link condition refuses every edge (a minimal torus), so only
    // opening the neck (moving one of the two a hair along its normal) removes them; the old normals
    // of those two faces are rounding noise and must not decide whether that move is valid.
    BlockMesh b;
    const std::array<double, 3> p[9] = {
        {44.7813554, 42.0425798, 80.8337389}, {48, 41.999999999999993, 84}, {48, 42, 84},
        {49.5595347, 40.8483184, 82.9723859}, {44.1156819, 40.0644688, 84.4453669}, {47.8149359, 43.7845916, 85.9048014},
        {50.8906951, 43.6205213, 83.7064036}, {47.9979001, 42.0014957, 83.9997829}, {49.1802861, 40.2894337, 86.8856933}};
    for (int k = 0; k < 9; ++k) {
        b.keys.push_back(makeEdgeKey(k, 0, 0, 0));
        b.positions.push_back(p[k]);
        b.finalAfterBlock.push_back(1);
    }
    b.triangles = {{0, 1, 2}, {3, 4, 0}, {0, 4, 5}, {0, 6, 3}, {7, 0, 2}, {6, 0, 7}, {5, 1, 0}, {8, 1, 7}, {4, 1, 8},
                   {1, 3, 2}, {4, 3, 1}, {5, 7, 1}, {7, 2, 3}, {7, 3, 8}, {3, 6, 8}, {8, 5, 4}, {5, 8, 6}, {6, 7, 5}};
    // Two unit tetrahedra span the rest of the volume (160 voxels): the move is 1e-5 of the diagonal.
    for (const std::array<double, 3> o : {std::array<double, 3>{5, 5, 5}, std::array<double, 3>{153, 153, 153}}) {
        const uint32_t base = uint32_t(b.keys.size());
        const std::array<double, 3> corners[4] = {{o[0], o[1], o[2]}, {o[0] + 1, o[1], o[2]}, {o[0], o[1] + 1, o[2]}, {o[0], o[1], o[2] + 1}};
        for (int k = 0; k < 4; ++k) {
            b.keys.push_back(makeEdgeKey(int32_t(base) + k, 0, 0, 0));
            b.positions.push_back(corners[k]);
            b.finalAfterBlock.push_back(1);
        }
        for (const auto& t : {std::array<uint32_t, 3>{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}})
            b.triangles.push_back({base + t[0], base + t[1], base + t[2]});
    }
    Decimator d;
    d.addBlock(b);
    d.requeueAll();
    d.decimateTo(0);
    EXPECT_EQ(d.faceCount(), 26u);  // a minimal torus and two tetrahedra: no collapse keeps them manifold
    EXPECT_EQ(d.removeDegenerateFaces(), 0u);
    const Mesh m = d.mesh();
    ASSERT_EQ(m.triangles.size(), 26u);
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (const auto& q : m.points)
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(q[k]));
            hi[k] = std::max(hi[k], double(q[k]));
        }
    const double diagonal2 = (hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) + (hi[2] - lo[2]) * (hi[2] - lo[2]);
    for (const auto& t : m.triangles) {
        std::array<double, 3> e1, e2;
        for (int k = 0; k < 3; ++k) {
            e1[k] = double(m.points[t[1]][k]) - double(m.points[t[0]][k]);
            e2[k] = double(m.points[t[2]][k]) - double(m.points[t[0]][k]);
        }
        const double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
        EXPECT_GT(0.5 * std::sqrt(cx * cx + cy * cy + cz * cz), 1e-12 * diagonal2);
    }
}

// An octahedron subdivided `levels` times and pushed onto an ellipsoid with semi-axes `axes`: faces of
// many sizes, every vertex final.
BlockMesh ellipsoid(int levels, std::array<double, 3> axes, double scale)
{
    std::vector<std::array<double, 3>> p = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    std::vector<std::array<uint32_t, 3>> t = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    for (int l = 0; l < levels; ++l) {
        std::vector<std::array<uint32_t, 3>> next;
        std::vector<std::pair<std::pair<uint32_t, uint32_t>, uint32_t>> mid;
        auto midpoint = [&](uint32_t a, uint32_t b) {
            const auto key = std::make_pair(std::min(a, b), std::max(a, b));
            for (const auto& [k, v] : mid)
                if (k == key) return v;
            std::array<double, 3> m{(p[a][0] + p[b][0]) / 2, (p[a][1] + p[b][1]) / 2, (p[a][2] + p[b][2]) / 2};
            const double len = std::sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]);
            p.push_back({m[0] / len, m[1] / len, m[2] / len});
            mid.push_back({key, uint32_t(p.size() - 1)});
            return uint32_t(p.size() - 1);
        };
        for (const auto& f : t) {
            const uint32_t a = midpoint(f[0], f[1]), b = midpoint(f[1], f[2]), c = midpoint(f[2], f[0]);
            next.insert(next.end(), {{f[0], a, c}, {a, f[1], b}, {c, b, f[2]}, {a, b, c}});
        }
        t = next;
    }
    BlockMesh b;
    for (size_t k = 0; k < p.size(); ++k) {
        b.keys.push_back(makeEdgeKey(int32_t(k), 0, 0, 0));
        b.positions.push_back({scale * axes[0] * p[k][0], scale * axes[1] * p[k][1], scale * axes[2] * p[k][2]});
        b.finalAfterBlock.push_back(1);
    }
    b.triangles = t;
    return b;
}

// RMS over the vertices of the distance from the ellipsoid with semi-axes `axes`, to first order
// (the implicit function's value over its gradient's length).
double rmsFromEllipsoid(const Mesh& m, std::array<double, 3> axes)
{
    double sum = 0;
    for (const auto& p : m.points) {
        double f = -1, g2 = 0;
        for (int k = 0; k < 3; ++k) {
            f += p[k] * p[k] / (axes[k] * axes[k]);
            g2 += 4 * p[k] * p[k] / (axes[k] * axes[k] * axes[k] * axes[k]);
        }
        sum += f * f / g2;
    }
    return std::sqrt(sum / double(m.points.size()));
}

// A torus of n x m quads, each split in two, outward: a closed surface, every vertex final.
BlockMesh torus(uint32_t n, uint32_t m)
{
    BlockMesh b;
    const double pi = std::acos(-1.0);
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t j = 0; j < m; ++j) {
            const double u = 2 * pi * i / n, v = 2 * pi * j / m, r = 10 + 3 * std::cos(v);
            b.keys.push_back(makeEdgeKey(int32_t(i), int32_t(j), 0, 0));
            b.positions.push_back({r * std::cos(u), r * std::sin(u), 3 * std::sin(v)});
            b.finalAfterBlock.push_back(1);
        }
    const auto at = [&](uint32_t i, uint32_t j) { return (i % n) * m + j % m; };
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t j = 0; j < m; ++j) {
            b.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
            b.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
        }
    return b;
}

TEST(Decimator, TakenMeshIsTheSameOnAnyThreadCount)
{
    // takeMesh collects the live vertices and faces in slot order on all threads, span by span, freeing
    // what each span has read; mesh() reads the same without freeing. A torus of 40,000 faces
    // decimated to 4,000 leaves dead slots in every span of both arrays (a span is 16,384 slots).
    const auto run = [](int threads) {
        tbb::task_arena arena(threads);
        return arena.execute([] {
            Decimator d;
            d.addBlock(torus(200, 100));
            d.decimateTo(4000);
            const size_t faces = d.faceCount(), vertices = d.vertexCount();
            const Mesh kept = d.mesh();
            const Mesh taken = d.takeMesh();
            EXPECT_EQ(taken.points, kept.points);
            EXPECT_EQ(taken.triangles, kept.triangles);
            EXPECT_EQ(taken.triangles.size(), faces);
            EXPECT_EQ(taken.points.size(), vertices);
            EXPECT_EQ(d.faceCount(), 0u) << "the decimator is left empty";
            EXPECT_GT(d.parallelSeconds(), 0.0) << "the collection's seconds stay";
            return taken;
        });
    };
    const Mesh one = run(1);
    EXPECT_EQ(one.triangles.size(), 4000u);
    testing::expectClosedOutward(one, false, "decimated torus");
    for (int threads : {2, 4}) {
        const Mesh m = run(threads);
        EXPECT_EQ(m.points, one.points) << threads << " threads";
        EXPECT_EQ(m.triangles, one.triangles) << threads << " threads";
    }
}

TEST(Decimator, RegionByRegionReachesTheTargetAsWellAsOnePass)
{
    // A finished mesh decimated in one pass and region by region along its long axis (x): the same face
    // count, both closed and outward, and about as close to the ellipsoid; one region is one pass.
    const std::array<double, 3> axes{24, 8, 4};
    const auto run = [&](size_t regions) {
        Decimator d;
        d.addBlock(ellipsoid(5, axes, 1.0));
        d.decimateRegionByRegion(1000, regions);
        return d.mesh();
    };
    const Mesh one = run(1), regions = run(16);
    Decimator plain;
    plain.addBlock(ellipsoid(5, axes, 1.0));
    plain.decimateTo(1000);
    EXPECT_EQ(one.triangles, plain.mesh().triangles);
    EXPECT_EQ(one.triangles.size(), 1000u);
    EXPECT_EQ(regions.triangles.size(), 1000u);
    EXPECT_NE(regions.triangles, one.triangles) << "the regions changed no collapse";
    testing::expectClosedOutward(one, false, "one pass");
    testing::expectClosedOutward(regions, false, "16 regions");
    const double errOne = rmsFromEllipsoid(one, axes), errRegions = rmsFromEllipsoid(regions, axes);
    std::printf("RMS distance from the ellipsoid: one pass %.5f, 16 regions %.5f\n", errOne, errRegions);
    EXPECT_LE(errRegions, 1.25 * errOne);
    // Every region takes its share: the faces left are spread along x like the vertices before.
    size_t leftHalf = 0;
    for (const auto& t : regions.triangles) leftHalf += regions.points[t[0]][0] + regions.points[t[1]][0] + regions.points[t[2]][0] < 0;
    EXPECT_NEAR(double(leftHalf), 500.0, 50.0);
}

TEST(Decimator, SameCollapsesInAnyUnitGivenTheVoxelArea)
{
    // Face weights have a floor relative to a voxel face's area: the same surface in units 8x larger
    // (a power of two: every product scales exactly), with the voxel area 64x larger, decimates the
    // same way. The faces straddle the floor (areas from about 0.2 to 1.5 voxel faces).
    auto run = [](double scale) {
        Decimator d;
        d.setVoxelArea(scale * scale);
        d.addBlock(ellipsoid(4, {24, 8, 4}, scale));
        d.decimateTo(200);
        return d.mesh();
    };
    const Mesh m1 = run(1.0), m8 = run(8.0);
    EXPECT_LE(m1.triangles.size(), 200u);
    EXPECT_EQ(m1.triangles, m8.triangles);
    ASSERT_EQ(m1.points.size(), m8.points.size());
    for (size_t i = 0; i < m1.points.size(); ++i)
        for (int k = 0; k < 3; ++k) EXPECT_EQ(8.0f * m1.points[i][k], m8.points[i][k]);
}

// The two halves of an ellipsoid (faces above and below z = 0) as two slabs: vertices of both halves
// are open in each, the others final.
std::array<BlockMesh, 2> ellipsoidHalves(int levels = 4)
{
    const BlockMesh whole = ellipsoid(levels, {24, 8, 4}, 1.0);
    std::vector<int> side(whole.keys.size(), 0);  // bit 0: used below, bit 1: used above
    auto above = [&](const std::array<uint32_t, 3>& t) {
        return whole.positions[t[0]][2] + whole.positions[t[1]][2] + whole.positions[t[2]][2] > 0;
    };
    for (const auto& t : whole.triangles)
        for (uint32_t v : t) side[v] |= above(t) ? 2 : 1;
    std::array<BlockMesh, 2> halves;
    for (int h = 0; h < 2; ++h) {
        std::vector<uint32_t> local(whole.keys.size(), UINT32_MAX);
        for (const auto& t : whole.triangles) {
            if (above(t) != (h == 1)) continue;
            std::array<uint32_t, 3> f;
            for (int k = 0; k < 3; ++k) {
                if (local[t[k]] == UINT32_MAX) {
                    local[t[k]] = uint32_t(halves[h].keys.size());
                    halves[h].keys.push_back(whole.keys[t[k]]);
                    halves[h].positions.push_back(whole.positions[t[k]]);
                    halves[h].finalAfterBlock.push_back(side[t[k]] == 3 ? 0 : 1);
                }
                f[k] = local[t[k]];
            }
            halves[h].triangles.push_back(f);
        }
    }
    return halves;
}

// A piece as another process reads it: written to bytes and read back.
SlabPiece afterTheTrip(SlabPiece&& piece)
{
    std::vector<char> bytes;
    writePieceBytes(std::move(piece), bytes);
    return readPieceBytes(bytes.data(), bytes.size());
}

TEST(Decimator, PieceAbsorbedAfterItsBytesGivesTheSameMesh)
{
    // A merge joins a piece made in this process or one read from the bytes another process sent:
    // the result must be the same mesh, collapse for collapse.
    auto run = [](bool throughBytes) {
        const std::array<BlockMesh, 2> halves = ellipsoidHalves();
        Decimator lower, upper;
        lower.addBlock(halves[0]);
        upper.addBlock(halves[1]);
        lower.decimateTo(300);
        upper.decimateTo(300);
        EXPECT_GT(upper.openVertices(), 10u);
        SlabPiece piece{upper.takePiece(), 1000, {}};
        EXPECT_EQ(upper.faceCount(), 0u);
        if (throughBytes) {
            piece = afterTheTrip(std::move(piece));
            EXPECT_EQ(piece.facesGenerated, 1000u);
        }
        lower.absorb(std::move(piece.mesh));
        EXPECT_EQ(lower.finalizeRemaining(), halves[0].keys.size() - size_t(std::count(halves[0].finalAfterBlock.begin(), halves[0].finalAfterBlock.end(), 1)));
        lower.decimateTo(120);
        return lower.mesh();
    };
    const Mesh home = run(false), travelled = run(true);
    EXPECT_LE(home.triangles.size(), 120u);
    EXPECT_EQ(home.triangles, travelled.triangles);
    EXPECT_EQ(home.points, travelled.points);
}

// A surface as a list of triangles of float positions, each started at its smallest corner (winding
// kept) and the list sorted: two meshes with the same faces compare equal in any order of numbering.
std::vector<std::array<std::array<float, 3>, 3>> faceSet(const Mesh& m)
{
    std::vector<std::array<std::array<float, 3>, 3>> faces;
    for (const auto& t : m.triangles) {
        std::array<std::array<float, 3>, 3> f{m.points[t[0]], m.points[t[1]], m.points[t[2]]};
        std::rotate(f.begin(), std::min_element(f.begin(), f.end()), f.end());
        faces.push_back(f);
    }
    std::sort(faces.begin(), faces.end());
    return faces;
}

TEST(Decimator, RetiringTheInteriorChangesNoFaceAndTravelsWithThePiece)
{
    // Two halves joined: the faces far from the seam just closed leave for the retired mesh, and the
    // surface is the same face for face; a piece of the retired decimator, through bytes or not,
    // absorbs into the same mesh; the passes after it never touch a retired face.
    const std::array<BlockMesh, 2> halves = ellipsoidHalves();
    Decimator d, upper;
    d.addBlock(halves[0]);
    upper.addBlock(halves[1]);
    d.decimateTo(2000);
    upper.decimateTo(2000);
    d.absorb(upper.takePiece());
    d.finalizeRemaining();
    const Mesh before = d.mesh();
    const size_t faces = d.faceCount();
    const size_t retired = d.retireInterior(2, 0.0);
    std::printf("%zu of %zu faces retired, %zu vertices left\n", retired, faces, d.vertexCount());
    EXPECT_GT(retired, faces / 4);
    EXPECT_LT(retired, faces);  // the seam's band stays
    EXPECT_EQ(d.retiredFaces(), retired);
    EXPECT_EQ(d.faceCount(), faces);
    const Mesh after = d.mesh();
    EXPECT_EQ(faceSet(after), faceSet(before));
    EXPECT_EQ(after.points.size(), before.points.size());
    const auto retiredSet = [&](const Mesh& m) {
        Mesh r;
        r.points = m.points;
        r.triangles.assign(m.triangles.begin(), m.triangles.begin() + std::ptrdiff_t(retired));
        return faceSet(r);
    };
    const auto kept = retiredSet(after);

    auto goOn = [&](bool throughBytes) {
        Decimator copy;
        SlabPiece piece{Decimator(d).takePiece(), 1000, {}, true};
        if (throughBytes) {
            piece = afterTheTrip(std::move(piece));
            EXPECT_TRUE(piece.roomSpent);
        }
        copy.absorb(std::move(piece.mesh));
        EXPECT_EQ(copy.retiredFaces(), retired);
        EXPECT_EQ(copy.faceCount(), faces);
        copy.decimateTo(retired + 100);
        copy.removeDegenerateFaces();
        return copy.mesh();
    };
    const Mesh home = goOn(false), travelled = goOn(true);
    EXPECT_EQ(home.triangles, travelled.triangles);
    EXPECT_EQ(home.points, travelled.points);
    EXPECT_LT(home.triangles.size(), faces);
    EXPECT_GE(home.triangles.size(), retired);
    EXPECT_EQ(retiredSet(home), kept);  // the retired faces come first, as they were
    testing::expectClosedOutward(home, false, "decimated after retiring");
}

TEST(Decimator, RetiredComponentsGoLikeLiveOnes)
{
    // Three closed ellipsoids of 128 faces, 1, 2 and 4 across. The middle one keeps live faces around
    // its six open corners (the rest of it retires, the corners between pinned); the others retire
    // whole. The clean-ups that remove whole components take retired faces along, and the output
    // keeps no point of theirs.
    BlockMesh b;
    for (int i = 0; i < 3; ++i) {
        const BlockMesh e = ellipsoid(2, {1.0, 0.8, 0.6}, double(1 << i));
        const uint32_t base = uint32_t(b.positions.size());
        for (size_t k = 0; k < e.positions.size(); ++k) {
            b.keys.push_back(makeEdgeKey(int32_t(base + k), 0, 0, 0));
            b.positions.push_back({e.positions[k][0] + 20.0 * i, e.positions[k][1], e.positions[k][2]});
            b.finalAfterBlock.push_back(i == 1 && k < 6 ? 0 : 1);
        }
        for (const auto& t : e.triangles) b.triangles.push_back({base + t[0], base + t[1], base + t[2]});
    }
    const auto retired = [&] {
        Decimator d;
        d.addBlock(b);
        d.retireInterior(0, 0.0);
        d.finalizeRemaining();
        return d;
    };
    const auto expectTheLargestAlone = [](const Decimator& d, const std::string& what) {
        EXPECT_EQ(d.faceCount(), 128u) << what;
        const Mesh m = d.mesh();
        EXPECT_EQ(m.triangles.size(), 128u) << what;
        EXPECT_EQ(m.points.size(), 66u) << what;
        for (const auto& p : m.points) EXPECT_GT(p[0], 30.0f) << what;  // the largest one is at x = 40
        testing::expectClosedOutward(m, false, what);
    };
    Decimator drop = retired();
    std::printf("%zu of 384 faces retired\n", drop.retiredFaces());
    EXPECT_GT(drop.retiredFaces(), 256u);
    EXPECT_LT(drop.retiredFaces(), 384u);
    EXPECT_EQ(drop.faceCount(), 384u);
    EXPECT_EQ(drop.dropSmallComponents(200), 2u);
    expectTheLargestAlone(drop, "dropSmallComponents");
    Decimator prune = retired();
    EXPECT_EQ(prune.pruneComponents(60.0), 2u);  // areas about 7, 30 and 120
    expectTheLargestAlone(prune, "pruneComponents");
}

TEST(Decimator, APieceKeepsWhyItsPairsWereRefused)
{
    // Pairs the bound refused in a slab stay the bound's after a merge, in this process or through the
    // bytes another process sends: the final pass reports what stopped it from them.
    for (const bool throughBytes : {false, true}) {
        std::array<BlockMesh, 2> halves = ellipsoidHalves();
        Decimator upper, lower;
        for (Decimator* d : {&upper, &lower}) d->setMaxError(1e-4);
        upper.addBlock(halves[1]);
        upper.decimateTo(0);
        ASSERT_TRUE(upper.boundRefusesAnEdge());
        SlabPiece piece{upper.takePiece(), 0, {}};
        if (throughBytes) {
            piece = afterTheTrip(std::move(piece));
        }
        EXPECT_FALSE(lower.boundRefusesAnEdge());
        lower.absorb(std::move(piece.mesh));
        EXPECT_TRUE(lower.boundRefusesAnEdge()) << (throughBytes ? "through bytes" : "in this process");
    }
}

TEST(Decimator, AQueueThatForgetsItsColdEntriesMakesTheSameCollapses)
{
    // A large queue drops the entries above the cost its pass reached and lists every edge again when
    // its heap runs out below that bar. Two halves of 16,384 faces decimated in passes, joined in
    // place, through a piece and through a piece's bytes, then decimated on: the absorbed side's queue
    // forgetting (the joined queue must then forget too), or both, gives the same mesh as every queue
    // keeping its entries. (Dropped stale entries come back at
    // their edge's cost of now, which a stale entry's bound reaches when it is popped; dropped dead
    // ones never come back.)
    enum class Join { InPlace, Piece, Bytes };
    struct Result {
        Mesh mesh;
        size_t queuedBeforeJoin = 0, collapses = 0;
    };
    auto run = [](int forgetting, Join join) {
        const bool forget = forgetting > 0;
        const std::array<BlockMesh, 2> halves = ellipsoidHalves(6);
        Decimator lower, upper;
        upper.setForgetAboveEntries(forgetting > 0 ? 0 : SIZE_MAX);
        lower.setForgetAboveEntries(forgetting > 1 ? 0 : SIZE_MAX);
        lower.addBlock(halves[0]);
        upper.addBlock(halves[1]);
        for (size_t target : {12000, 8000, 5000, 3000})
            for (Decimator* d : {&lower, &upper}) d->decimateTo(target);
        Result r;
        r.queuedBeforeJoin = lower.queued() + upper.queued();
        if (join == Join::InPlace) {
            lower.absorb(std::move(upper));
        } else {
            SlabPiece piece{upper.takePiece(), 0, {}};
            EXPECT_EQ(piece.mesh.forgetFromBits != 0, forget);
            if (join == Join::Bytes) {
                const uint32_t bar = piece.mesh.forgetFromBits;
                piece = afterTheTrip(std::move(piece));
                EXPECT_EQ(piece.mesh.forgetFromBits, bar);
            }
            lower.absorb(std::move(piece.mesh));
        }
        lower.finalizeRemaining();
        for (size_t target : {2000, 1000, 400}) lower.decimateTo(target);
        r.mesh = lower.mesh();
        r.collapses = lower.work().collapses;
        return r;
    };
    for (Join join : {Join::InPlace, Join::Piece, Join::Bytes})
      for (int forgetting : {1, 2}) {
        SCOPED_TRACE("join " + std::to_string(int(join)) + ", queues forgetting " + std::to_string(forgetting));
        const Result kept = run(0, join), forgot = run(forgetting, join);
        std::printf("queued before the join: %zu kept, %zu with %d forgetting; %zu collapses\n", kept.queuedBeforeJoin,
                    forgot.queuedBeforeJoin, forgetting, kept.collapses);
        EXPECT_LT(forgot.queuedBeforeJoin, kept.queuedBeforeJoin * (forgetting == 2 ? 2 : 3) / 4) << "most of a queue lay above its bar";
        EXPECT_EQ(forgot.mesh.triangles.size(), 400u);
        EXPECT_EQ(forgot.collapses, kept.collapses);
        EXPECT_EQ(forgot.mesh.triangles, kept.mesh.triangles);
        EXPECT_EQ(forgot.mesh.points, kept.mesh.points);
        testing::expectClosedOutward(forgot.mesh, false, "forgetting queues");
    }
}

TEST(Decimator, ADecimatorAbsorbedInPlaceGivesThePiecesMesh)
{
    // A merge in one process reads the other decimator's arrays in place instead of a piece taken
    // from it: the same mesh, the same queue work collapse for collapse, and under an error bound the
    // same drift carried over (the largest accepted error and the faces the bound leaves).
    struct Result {
        Mesh mesh;
        QueueWork work;
        size_t queuedAfterAbsorb = 0;
        double maxError = 0;
    };
    auto run = [](bool inPlace, double bound) {
        const std::array<BlockMesh, 2> halves = ellipsoidHalves();
        Decimator lower, upper;
        if (bound > 0)
            for (Decimator* d : {&lower, &upper}) d->setMaxError(bound);
        lower.addBlock(halves[0]);
        upper.addBlock(halves[1]);
        lower.decimateTo(300);
        upper.decimateTo(300);
        if (inPlace) lower.absorb(std::move(upper));
        else lower.absorb(upper.takePiece());
        EXPECT_EQ(upper.faceCount(), 0u);
        EXPECT_EQ(upper.vertexCount(), 0u);
        EXPECT_EQ(upper.queued(), 0u);
        Result r;
        r.queuedAfterAbsorb = lower.queued();
        lower.finalizeRemaining();
        lower.decimateTo(bound > 0 ? 0 : 120);
        r.mesh = lower.mesh();
        r.work = lower.work();
        r.maxError = lower.maxErrorAccepted();
        return r;
    };
    for (double bound : {0.0, 0.03}) {
        const Result piece = run(false, bound), inPlace = run(true, bound);
        std::printf("bound %.2f: %zu faces, %zu queued after the absorb, %llu pops, %llu collapses, largest error %.4f\n",
                    bound, piece.mesh.triangles.size(), piece.queuedAfterAbsorb, (unsigned long long)piece.work.pops,
                    (unsigned long long)piece.work.collapses, piece.maxError);
        EXPECT_GT(piece.work.stale, 0u) << "stale entries cross the merge";
        EXPECT_EQ(inPlace.mesh.triangles, piece.mesh.triangles);
        EXPECT_EQ(inPlace.mesh.points, piece.mesh.points);
        EXPECT_EQ(inPlace.queuedAfterAbsorb, piece.queuedAfterAbsorb);
        EXPECT_EQ(inPlace.work.pops, piece.work.pops);
        EXPECT_EQ(inPlace.work.stale, piece.work.stale);
        EXPECT_EQ(inPlace.work.collapses, piece.work.collapses);
        EXPECT_EQ(inPlace.maxError, piece.maxError);
        testing::expectClosedOutward(inPlace.mesh, false, "absorbed in place");
    }
}

TEST(Decimator, APieceAbsorbedIntoAnEmptyDecimatorGoesOnAsItsDecimatorWould)
{
    // A piece renumbers the live vertices in id order, which keeps every tie of the queue's order;
    // it drops dead queue entries, keeps stale ones stale, carries the drift under an error bound.
    // Absorbed into an empty decimator (in place or through the piece), the pass that follows makes
    // the same collapses as the original decimator going on by itself (under the bound, the drift
    // decides which): an independent check of what the take keeps.
    for (double bound : {0.0, 0.15}) {
        for (bool inPlace : {false, true}) {
            const std::array<BlockMesh, 2> halves = ellipsoidHalves();
            Decimator original, taken, fresh;
            if (bound > 0)
                for (Decimator* d : {&original, &fresh}) d->setMaxError(bound);
            original.addBlock(halves[0]);
            original.finalizeRemaining();
            original.decimateTo(600);
            // A pass starts by sending back to the queue the refused pairs whose faces changed since;
            // a piece's refused pairs count as unchanged (a merge changes no face around them).
            original.decimateTo(600);
            taken = original;
            if (inPlace) fresh.absorb(std::move(taken));
            else fresh.absorb(taken.takePiece());
            const QueueWork before = original.work();
            original.decimateTo(bound > 0 ? 0 : 150);
            fresh.decimateTo(bound > 0 ? 0 : 150);
            const QueueWork went = original.work() - before, goes = fresh.work();
            SCOPED_TRACE(std::string(inPlace ? "in place" : "through a piece") + ", bound " + std::to_string(bound));
            EXPECT_GT(bound > 0 ? went.collapses : went.stale, 0u);
            EXPECT_EQ(goes.collapses, went.collapses);
            EXPECT_EQ(goes.stale, went.stale);
            EXPECT_EQ(goes.attempts, went.attempts);
            const Mesh a = original.mesh(), b = fresh.mesh();
            EXPECT_EQ(b.triangles, a.triangles);
            EXPECT_EQ(b.points, a.points);
        }
    }
}

TEST(Decimator, AParkedNodeGoesOnWithItsSettingsAndQueue)
{
    // A finished node of the merge tree is parked while it waits (its mesh moved out into a piece,
    // the decimator emptied) and absorbs the piece back before its join. Under an error bound, with a
    // relaxed normal turn and a voxel area: the same work counted, the same faces and closed, and the
    // bound still holding after the join (a decimator that lost its settings would collapse past it).
    struct Result {
        Mesh mesh;
        QueueWork work;
        double maxError = 0;
    };
    auto run = [](bool parked) {
        const std::array<BlockMesh, 2> halves = ellipsoidHalves();
        Decimator lower, upper;
        for (Decimator* d : {&lower, &upper}) {
            d->setMaxError(0.05);
            d->setVoxelArea(0.25);
            d->setMaxNormalTurn(0.0);
        }
        lower.addBlock(halves[0]);
        upper.addBlock(halves[1]);
        lower.decimateTo(0);
        upper.decimateTo(0);
        if (parked) {
            const QueueWork before = lower.work();
            MeshPiece piece = lower.park();
            EXPECT_EQ(lower.faceCount(), 0u);
            EXPECT_EQ(lower.work().pops, before.pops);
            lower.absorb(std::move(piece));
        }
        lower.absorb(upper.takePiece());
        lower.finalizeRemaining();
        lower.decimateTo(0);
        return Result{lower.mesh(), lower.work(), lower.maxErrorAccepted()};
    };
    const Result home = run(false), parked = run(true);
    std::printf("error bound 0.05: %zu faces without parking, %zu parked; largest error %.4f / %.4f\n",
                home.mesh.triangles.size(), parked.mesh.triangles.size(), home.maxError, parked.maxError);
    EXPECT_LE(parked.maxError, 0.05);
    EXPECT_GT(parked.mesh.triangles.size(), 100u) << "the bound stops the collapses well above a handful of faces";
    EXPECT_NEAR(double(parked.mesh.triangles.size()), double(home.mesh.triangles.size()), 0.02 * double(home.mesh.triangles.size()));
    EXPECT_NEAR(double(parked.work.collapses), double(home.work.collapses), 0.02 * double(home.work.collapses));
    testing::expectClosedOutward(parked.mesh, false, "parked");
}

TEST(Decimator, SealingTheOpenVerticesBetweenBlocksChangesNothing)
{
    // A finished node keeps its open vertices sorted (seal); a block added after that moves them back
    // to the hash map. The welds, hence the mesh, are the same as without the round trip.
    auto run = [](bool sealBetween) {
        const std::array<BlockMesh, 2> halves = ellipsoidHalves();
        Decimator d;
        d.addBlock(halves[0]);
        const size_t open = d.openVertices();
        if (sealBetween) {
            d.seal();
            EXPECT_EQ(d.openVertices(), open);
        }
        d.addBlock(halves[1]);
        d.seal();
        d.finalizeRemaining();
        EXPECT_EQ(d.openVertices(), 0u);
        d.decimateTo(150);
        return d.mesh();
    };
    const Mesh plain = run(false), sealed = run(true);
    EXPECT_LE(plain.triangles.size(), 150u);
    EXPECT_EQ(plain.triangles, sealed.triangles);
    EXPECT_EQ(plain.points, sealed.points);
}

TEST(Decimator, PieceBytesThatEndEarlyAreRefused)
{
    const std::array<BlockMesh, 2> halves = ellipsoidHalves();
    Decimator d;
    d.addBlock(halves[1]);
    std::vector<char> bytes;
    writePieceBytes(SlabPiece{d.takePiece(), 0, {}}, bytes);
    for (size_t cut : {size_t(0), size_t(7), bytes.size() / 2, bytes.size() - 1})
        EXPECT_THROW(readPieceBytes(bytes.data(), cut), std::runtime_error) << cut;
    EXPECT_NO_THROW(readPieceBytes(bytes.data(), bytes.size()));
}

// A mesh's vertices as one block, every vertex final; keys lie in the plane z = `plane` of edge keys, so
// blocks made with different planes never share a vertex.
BlockMesh finalBlock(const Mesh& m, int32_t plane)
{
    BlockMesh b;
    for (size_t k = 0; k < m.points.size(); ++k) {
        b.keys.push_back(makeEdgeKey(int32_t(k % 100000), int32_t(k / 100000), plane, 0));
        b.positions.push_back({m.points[k][0], m.points[k][1], m.points[k][2]});
        b.finalAfterBlock.push_back(1);
    }
    b.triangles = m.triangles;
    return b;
}

TEST(Decimator, RelaxedTurnRetriesFoldsNotTopology)
{
    // Marching Cubes on a random sparse level set (40k faces, many small components), decimated until
    // stuck at the default turn: what is left are pairs that would fold a face and pairs the link
    // condition refuses. Tetrahedra beside it, on keys of their own, are refused for their topology only.
    testing::GridSpec spec;
    spec.anisotropic = false;
    BlockMesh b = finalBlock(testing::denseMarchingCubes(*testing::randomSparseGrid(spec), 0.0), 0);
    const BlockMesh t = tetrahedra(20);
    const uint32_t base = uint32_t(b.keys.size());
    for (size_t k = 0; k < t.keys.size(); ++k) {
        b.keys.push_back(makeEdgeKey(int32_t(k), 0, 1, 0));
        b.positions.push_back({t.positions[k][0], t.positions[k][1] + 500, t.positions[k][2]});
        b.finalAfterBlock.push_back(1);
    }
    for (const auto& f : t.triangles) b.triangles.push_back({base + f[0], base + f[1], base + f[2]});
    Decimator d;
    d.addBlock(b);
    ASSERT_EQ(d.vertexCount(), b.keys.size()) << "every key is a vertex of its own";
    while (d.decimateTo(0) > 0) {
    }
    const size_t stuck = d.faceCount();
    Decimator all = d;
    const uint64_t before = d.collapseAttempts();
    d.retryFolds();
    EXPECT_EQ(d.decimateTo(0), 0u);
    all.requeueAll();
    EXPECT_EQ(all.decimateTo(0), 0u);
    const uint64_t folds = d.collapseAttempts() - before, every = all.collapseAttempts() - before;
    std::printf("%zu faces stuck at %zu; a retry of the folds tries %llu pairs, a full requeue %llu\n", b.triangles.size(),
                stuck, (unsigned long long)folds, (unsigned long long)every);
    EXPECT_GT(folds, 0u);
    // The tetrahedra's 120 pairs and the noise's own topology refusals wait.
    EXPECT_LE(folds + 120, every);
    EXPECT_LT(10 * folds, every) << "most stuck pairs are refused for their topology";
    // A relaxed turn lets folding pairs go.
    d.setMaxNormalTurn(-0.6);
    d.retryFolds();
    EXPECT_GT(d.decimateTo(0), 0u);
    EXPECT_LT(d.faceCount(), stuck);
    testing::expectClosedOutward(d.mesh(), false, "relaxed");
}

TEST(Decimator, ErrorBoundHoldsOnASphere)
{
    // A finely subdivided sphere of radius 10 decimated as far as the bound allows: every vertex, face
    // centroid and edge midpoint of the result stays within 2E of the sphere (checked on the geometry,
    // not on the decimator's own estimate), and a smaller bound keeps more faces.
    const auto farthest = [](const Mesh& m) {
        const auto radius = [](std::array<double, 3> p) { return std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]); };
        double worst = 0;
        for (const auto& t : m.triangles) {
            std::array<double, 3> c[3];
            for (int k = 0; k < 3; ++k) c[k] = {m.points[t[k]][0], m.points[t[k]][1], m.points[t[k]][2]};
            const std::array<double, 3> samples[] = {
                c[0], {(c[0][0] + c[1][0] + c[2][0]) / 3, (c[0][1] + c[1][1] + c[2][1]) / 3, (c[0][2] + c[1][2] + c[2][2]) / 3},
                {(c[0][0] + c[1][0]) / 2, (c[0][1] + c[1][1]) / 2, (c[0][2] + c[1][2]) / 2}};
            for (const auto& q : samples) worst = std::max(worst, std::abs(radius(q) - 10.0));
        }
        return worst;
    };
    Decimator input;
    input.addBlock(ellipsoid(5, {1, 1, 1}, 10.0));
    // The input is a polyhedron inscribed in the sphere: its own faces sit slightly inside.
    const double inscribed = farthest(input.mesh());
    size_t previous = 0;
    for (const double e : {0.2, 0.05, 0.01}) {
        Decimator d;
        d.setMaxError(e);
        d.addBlock(ellipsoid(5, {1, 1, 1}, 10.0));
        d.decimateTo(0);
        EXPECT_LE(d.maxErrorAccepted(), e);
        EXPECT_TRUE(d.boundRefusesAnEdge()) << "the bound, not the sphere's topology, keeps these faces; E = " << e;
        const Mesh m = d.mesh();
        EXPECT_GT(m.triangles.size(), previous) << "E = " << e;
        previous = m.triangles.size();
        const double worst = farthest(m);
        std::printf("E = %g: %zu faces, largest distance from the sphere %.4g (input %.4g)\n", e, m.triangles.size(), worst,
                    inscribed);
        EXPECT_LE(worst, 2 * e + inscribed) << "E = " << e;
    }
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

TEST(Decimator, ABoundThatRefusesNothingLeavesTheTopologyToSayWhy)
{
    // An octahedron under a bound far above its size goes down to the tetrahedron, where the link
    // condition, not the bound, refuses every edge; under a bound below its first collapse's error,
    // the bound refuses edges the topology allows.
    for (const double bound : {1e9, 1e-6}) {
        Decimator d;
        d.setMaxError(bound);
        d.addBlock(octahedron({0, 0, 0}, 0));
        for (int pass = 0; pass < 4; ++pass) d.decimateTo(0);
        if (bound > 1) {
            EXPECT_EQ(d.faceCount(), 4u);
            EXPECT_FALSE(d.boundRefusesAnEdge());
        } else {
            EXPECT_EQ(d.faceCount(), 8u);
            EXPECT_TRUE(d.boundRefusesAnEdge());
        }
    }
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

