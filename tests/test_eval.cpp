// Tests of the evaluation library: mesh statistics on hand-built meshes with known answers, the
// point-to-triangle distance and its BVH against brute force, metro-style distance on spheres with
// a known offset, mesh file round trips, and the OpenMesh decimation baseline.
#include "eval_openmesh.h"
#include "mesh_error.h"
#include "mesh_io.h"
#include "mesh_stats.h"
#include "reference_decimate.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <string>

#include <unistd.h>

using namespace vdb_isosimp;
using namespace vdb_isosimp::eval;
using Vec = std::array<double, 3>;

namespace {

// Unit icosphere: icosahedron with each triangle split in 4 `levels` times, vertices projected to
// the sphere; 20 * 4^levels counter-clockwise (outward) triangles.
Mesh icosphere(int levels) {
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    Mesh m;
    m.points = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    m.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                   {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                   {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
    auto normalize = [](std::array<float, 3> p) {
        const double l = std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]);
        return std::array<float, 3>{float(p[0] / l), float(p[1] / l), float(p[2] / l)};
    };
    for (auto& p : m.points) p = normalize(p);
    for (int level = 0; level < levels; ++level) {
        std::map<std::pair<uint32_t, uint32_t>, uint32_t> midpoint;
        auto mid = [&](uint32_t a, uint32_t b) {
            const auto key = std::minmax(a, b);
            const auto it = midpoint.find(key);
            if (it != midpoint.end()) return it->second;
            const auto &pa = m.points[a], &pb = m.points[b];
            m.points.push_back(normalize({pa[0] + pb[0], pa[1] + pb[1], pa[2] + pb[2]}));
            return midpoint[key] = uint32_t(m.points.size() - 1);
        };
        std::vector<std::array<uint32_t, 3>> next;
        for (const auto& tri : m.triangles) {
            const uint32_t ab = mid(tri[0], tri[1]), bc = mid(tri[1], tri[2]), ca = mid(tri[2], tri[0]);
            next.push_back({tri[0], ab, ca});
            next.push_back({tri[1], bc, ab});
            next.push_back({tri[2], ca, bc});
            next.push_back({ab, bc, ca});
        }
        m.triangles = std::move(next);
    }
    return m;
}

Mesh scaled(Mesh m, float s) {
    for (auto& p : m.points)
        for (float& c : p) c *= s;
    return m;
}

// Unit cube [0,1]^3, two counter-clockwise (outward) triangles per side; triangles 2k and 2k+1
// form side k.
Mesh cube() {
    Mesh m;
    m.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};
    m.triangles = {{0, 2, 1}, {0, 3, 2},  // z = 0
                   {4, 5, 6}, {4, 6, 7},  // z = 1
                   {0, 1, 5}, {0, 5, 4},  // y = 0
                   {3, 7, 6}, {3, 6, 2},  // y = 1
                   {0, 4, 7}, {0, 7, 3},  // x = 0
                   {1, 2, 6}, {1, 6, 5}}; // x = 1
    return m;
}

Mesh tetrahedron(std::array<float, 3> o) {
    Mesh m;
    m.points = {o, {o[0] + 1, o[1], o[2]}, {o[0], o[1] + 1, o[2]}, {o[0], o[1], o[2] + 1}};
    m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    return m;
}

Mesh append(Mesh a, const Mesh& b) {
    const uint32_t base = uint32_t(a.points.size());
    a.points.insert(a.points.end(), b.points.begin(), b.points.end());
    for (auto t : b.triangles) a.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
    return a;
}

Vec toVec(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }
double dist2(const Vec& a, const Vec& b) {
    return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
}

std::string tempPath(const std::string& name) {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    return (std::filesystem::temp_directory_path() /
            ("test_eval_" + std::string(info->name()) + "_" + std::to_string(::getpid()) + "_" + name))
        .string();
}

} // namespace

// ---------------------------------------------------------------------------------------------
// mesh_stats

TEST(MeshStats, ClosedCube) {
    const MeshStats s = computeMeshStats(cube());
    EXPECT_EQ(s.vertices, 8u);
    EXPECT_EQ(s.referencedVertices, 8u);
    EXPECT_EQ(s.faces, 12u);
    EXPECT_EQ(s.edges, 18u);
    EXPECT_EQ(s.boundaryEdges, 0u);
    EXPECT_EQ(s.nonManifoldEdges, 0u);
    EXPECT_EQ(s.misorientedEdges, 0u);
    EXPECT_EQ(s.nonManifoldVertices, 0u);
    EXPECT_EQ(s.zeroAreaFaces, 0u);
    EXPECT_EQ(s.components, 1u);
    EXPECT_EQ(s.eulerCharacteristic, 2);
    EXPECT_TRUE(s.closed());
    EXPECT_TRUE(s.manifold());
    EXPECT_TRUE(s.oriented());
    EXPECT_NEAR(s.signedVolume, 1.0, 1e-12);
    EXPECT_NEAR(s.area, 6.0, 1e-12);
    EXPECT_NEAR(s.minAngleP1, 45.0, 1e-4); // every triangle is a right isosceles one
    EXPECT_NEAR(s.minAngleP50, 45.0, 1e-4);
    EXPECT_NEAR(s.bboxDiagonal, std::sqrt(3.0), 1e-12);
    EXPECT_EQ(s.bboxMin[0], 0.0);
    EXPECT_EQ(s.bboxMax[2], 1.0);
}

TEST(MeshStats, CubeWithOneTriangleFlipped) {
    Mesh m = cube();
    std::swap(m.triangles[3][1], m.triangles[3][2]);
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.misorientedEdges, 3u);
    EXPECT_EQ(s.boundaryEdges, 0u);
    EXPECT_TRUE(s.closed());
    EXPECT_TRUE(s.manifold());
    EXPECT_FALSE(s.oriented());
    // The flipped triangle's tetrahedron changes sign: volume 1 - 2 * (its contribution).
    EXPECT_LT(s.signedVolume, 1.0 - 1e-6);
}

TEST(MeshStats, CubeWithOneSideFlipped) {
    Mesh m = cube();
    for (int k : {2, 3}) std::swap(m.triangles[size_t(k)][1], m.triangles[size_t(k)][2]);
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.misorientedEdges, 4u); // the side's diagonal stays consistent
    EXPECT_TRUE(s.closed());
}

TEST(MeshStats, CubeWithOneTriangleRemoved) {
    Mesh m = cube();
    m.triangles.erase(m.triangles.begin() + 5);
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.boundaryEdges, 3u);
    EXPECT_EQ(s.nonManifoldEdges, 0u);
    EXPECT_EQ(s.misorientedEdges, 0u);
    EXPECT_EQ(s.nonManifoldVertices, 0u);
    EXPECT_FALSE(s.closed());
    EXPECT_TRUE(s.manifold());
    EXPECT_EQ(s.eulerCharacteristic, 1); // a disc
}

TEST(MeshStats, TwoTetrahedraSharingOneVertex) {
    // b's vertex 1 lies at (0,0,0), a's vertex 0; the two solids touch only there.
    Mesh m = append(tetrahedron({0, 0, 0}), tetrahedron({-1, 0, 0}));
    for (auto& t : m.triangles)
        for (auto& v : t)
            if (v == 5) v = 0; // weld; point 5 stays as an unreferenced duplicate
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.referencedVertices, 7u);
    EXPECT_EQ(s.vertices, 8u);
    EXPECT_EQ(s.nonManifoldVertices, 1u);
    EXPECT_EQ(s.nonManifoldEdges, 0u);
    EXPECT_EQ(s.boundaryEdges, 0u);
    EXPECT_EQ(s.misorientedEdges, 0u);
    EXPECT_EQ(s.components, 1u);
    EXPECT_TRUE(s.closed());
    EXPECT_FALSE(s.manifold());
    EXPECT_NEAR(s.signedVolume, 2.0 / 6.0, 1e-12);
}

TEST(MeshStats, BowtieIsNonManifoldVertex) {
    Mesh m;
    m.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}};
    m.triangles = {{0, 1, 2}, {0, 3, 4}};
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.nonManifoldVertices, 1u);
    EXPECT_EQ(s.boundaryEdges, 6u);
    EXPECT_EQ(s.components, 1u);
}

TEST(MeshStats, OpenFanIsManifold) {
    // Four triangles around vertex 0 listed out of fan order: still one fan.
    Mesh m;
    m.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {-1, 0, 0}, {0, -1, 0}};
    m.triangles = {{0, 3, 4}, {0, 1, 2}, {0, 2, 3}};
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.nonManifoldVertices, 0u);
    EXPECT_EQ(s.boundaryEdges, 5u);
    EXPECT_EQ(s.misorientedEdges, 0u);
    EXPECT_TRUE(s.manifold());
}

TEST(MeshStats, ThreeTrianglesOnOneEdge) {
    Mesh m;
    m.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
    m.triangles = {{0, 1, 2}, {1, 0, 3}, {1, 0, 4}};
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.nonManifoldEdges, 1u);
    EXPECT_EQ(s.boundaryEdges, 6u);
    EXPECT_EQ(s.nonManifoldVertices, 0u);
    EXPECT_EQ(s.edges, 7u);
    EXPECT_FALSE(s.manifold());
    EXPECT_FALSE(s.closed());
}

TEST(MeshStats, ZeroAreaTriangles) {
    Mesh m;
    m.points = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}, {0, 0, 1e-3f}};
    m.triangles = {{0, 1, 3}, {0, 1, 2}, {0, 1, 4}}; // regular, collinear, thin (area 5e-4)
    const MeshStats exact = computeMeshStats(m);
    EXPECT_EQ(exact.zeroAreaFaces, 1u);
    EXPECT_EQ(exact.minAngleP1, 0.0);
    const MeshStats loose = computeMeshStats(m, 1e-3);
    EXPECT_EQ(loose.zeroAreaFaces, 2u);
    // Repeated index: zero area too.
    m.triangles = {{0, 1, 1}};
    EXPECT_EQ(computeMeshStats(m).zeroAreaFaces, 1u);
}

TEST(MeshStats, ComponentsAndUnreferencedVertices) {
    Mesh m = append(cube(), scaled(cube(), 0.5f));
    m.points.push_back({5, 5, 5}); // unreferenced: must not count nor stretch the box
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.components, 2u);
    EXPECT_EQ(s.eulerCharacteristic, 4);
    EXPECT_EQ(s.vertices, 17u);
    EXPECT_EQ(s.referencedVertices, 16u);
    EXPECT_NEAR(s.bboxDiagonal, std::sqrt(3.0), 1e-12);
    EXPECT_NEAR(s.signedVolume, 1.125, 1e-12);
}

TEST(MeshStats, Icosphere) {
    const Mesh m = icosphere(4);
    const MeshStats s = computeMeshStats(m);
    EXPECT_EQ(s.faces, 5120u);
    EXPECT_EQ(s.eulerCharacteristic, 2);
    EXPECT_TRUE(s.closed());
    EXPECT_TRUE(s.manifold());
    EXPECT_TRUE(s.oriented());
    EXPECT_EQ(s.components, 1u);
    EXPECT_GT(s.signedVolume, 0.99 * 4.0 / 3.0 * M_PI); // inscribed: slightly less than the ball
    EXPECT_LT(s.signedVolume, 4.0 / 3.0 * M_PI);
    EXPECT_GT(s.minAngleP1, 45.0); // subdivided icosahedra have near-equilateral triangles
}

TEST(MeshStats, RejectsOutOfRangeIndex) {
    Mesh m = cube();
    m.triangles[0][0] = 8;
    EXPECT_THROW(computeMeshStats(m), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// point-to-triangle distance and BVH

TEST(Distance, ClosestPointMatchesDenseSampling) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    const int n = 200; // barycentric grid resolution
    for (int trial = 0; trial < 200; ++trial) {
        const Vec a{u(rng), u(rng), u(rng)}, b{u(rng), u(rng), u(rng)}, c{u(rng), u(rng), u(rng)};
        const Vec p{2 * u(rng), 2 * u(rng), 2 * u(rng)};
        const double d = std::sqrt(dist2(p, closestPointOnTriangle(p, a, b, c)));
        double best = HUGE_VAL;
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) {
                const double s = double(i) / n, t = double(j) / n, r = 1 - s - t;
                const Vec q{r * a[0] + s * b[0] + t * c[0], r * a[1] + s * b[1] + t * c[1],
                            r * a[2] + s * b[2] + t * c[2]};
                best = std::min(best, dist2(p, q));
            }
        best = std::sqrt(best);
        // The exact distance can't exceed any sampled one, and the grid is at most one cell
        // (< longest edge / n) away from the true closest point.
        const double edge = std::sqrt(std::max({dist2(a, b), dist2(b, c), dist2(c, a)}));
        EXPECT_LE(d, best + 1e-12) << "trial " << trial;
        EXPECT_GE(d, best - edge / n) << "trial " << trial;
    }
}

TEST(Distance, ClosestPointOnDegenerateTriangles) {
    const Vec p{0.5, 1, 0};
    // Collinear corners: closest point on the segment [(0,0,0), (2,0,0)].
    Vec q = closestPointOnTriangle(p, {0, 0, 0}, {1, 0, 0}, {2, 0, 0});
    EXPECT_NEAR(dist2(p, q), 1.0, 1e-15);
    // All corners equal.
    q = closestPointOnTriangle(p, {1, 0, 0}, {1, 0, 0}, {1, 0, 0});
    EXPECT_NEAR(dist2(p, q), 1.25, 1e-15);
    // Two corners equal.
    q = closestPointOnTriangle({3, 1, 0}, {0, 0, 0}, {0, 0, 0}, {2, 0, 0});
    EXPECT_NEAR(dist2({3, 1, 0}, q), 2.0, 1e-15);
}

TEST(Distance, BvhMatchesBruteForce) {
    // Triangle soup of mixed sizes, including degenerate triangles and shared vertices.
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<float> u(0, 1), small(-0.05f, 0.05f);
    Mesh m;
    for (int i = 0; i < 3000; ++i) {
        const std::array<float, 3> o{u(rng), u(rng), u(rng)};
        const float s = i % 10 == 0 ? 5.0f : 1.0f;
        const uint32_t base = uint32_t(m.points.size());
        m.points.push_back(o);
        m.points.push_back({o[0] + s * small(rng), o[1] + s * small(rng), o[2] + s * small(rng)});
        if (i % 50 == 0)
            m.points.push_back(m.points.back()); // degenerate: two equal corners
        else
            m.points.push_back({o[0] + s * small(rng), o[1] + s * small(rng), o[2] + s * small(rng)});
        m.triangles.push_back({base, base + 1, base + 2});
        if (i > 0 && i % 3 == 0) m.triangles.push_back({base, base - 2, base + 1}); // shared vertices
    }
    const TriangleBVH bvh(m);
    std::uniform_real_distribution<double> q(-0.5, 1.5);
    for (int i = 0; i < 2000; ++i) {
        const Vec p{q(rng), q(rng), q(rng)};
        double brute = HUGE_VAL;
        for (const auto& t : m.triangles)
            brute = std::min(brute, dist2(p, closestPointOnTriangle(p, toVec(m.points[t[0]]), toVec(m.points[t[1]]),
                                                                    toVec(m.points[t[2]]))));
        const TriangleBVH::Hit hit = bvh.nearest(p);
        ASSERT_EQ(hit.distanceSquared, brute) << "query " << i; // same arithmetic, so exactly equal
        ASSERT_EQ(dist2(p, hit.point), hit.distanceSquared);
        const auto& t = m.triangles[hit.triangle];
        ASSERT_EQ(dist2(p, closestPointOnTriangle(p, toVec(m.points[t[0]]), toVec(m.points[t[1]]),
                                                  toVec(m.points[t[2]]))),
                  brute);
    }
}

TEST(Distance, BvhQueriesOnSurfacePoints) {
    // Points on the mesh itself: distance 0 (the typical query of the evaluation).
    const Mesh m = icosphere(3);
    const TriangleBVH bvh(m);
    for (const auto& p : m.points) EXPECT_EQ(bvh.nearest(toVec(p)).distanceSquared, 0.0);
}

// ---------------------------------------------------------------------------------------------
// metro-style distance

// A = unit icosphere (81,920 triangles), B = A scaled by 1.01. Every face of B is the matching face
// of A pushed out along its plane normal by 0.01 * h, where h is the distance of A's face plane from
// the centre; the chordal error of level 6 puts h within 5e-5 of 1. Both spheres are convex, so a
// point on A is 0.01 * h from B, and a point on B is at least that (slightly more near edges) from
// A; B's vertices are exactly 0.01 from A's. So mean, RMS and max all lie within 0.01 * (1 +- 1e-3),
// far tighter than the 2% asked for.
TEST(Distance, ScaledSphere) {
    const Mesh a = icosphere(6);
    const Mesh b = scaled(a, 1.01f);
    ASSERT_EQ(a.triangles.size(), 81920u);
    const SymmetricDistance d = symmetricDistance(a, b);
    for (const DistanceStats* s : {&d.ab, &d.ba}) {
        EXPECT_EQ(s->samples, defaultSampleCount(a.triangles.size()));
        EXPECT_EQ(s->vertexQueries, a.points.size());
        for (double v : {s->mean, s->rms, s->max}) {
            EXPECT_GT(v, 0.0098);
            EXPECT_LT(v, 0.0102);
            EXPECT_NEAR(v, 0.01, 1e-5);
        }
    }
    EXPECT_NEAR(d.ab.diagonal, 2 * std::sqrt(3.0), 0.01);
    EXPECT_EQ(d.hausdorff, std::max(d.ab.max, d.ba.max));
    // B's vertices sit exactly 0.01 * |v| outside A's vertices, which are the nearest points.
    EXPECT_NEAR(d.ba.max, 0.01, 1e-6);
}

TEST(Distance, IdenticalMeshesHaveZeroDistance) {
    const Mesh a = icosphere(3);
    const DistanceStats d = sampleDistance(a, a, 10000, 3);
    EXPECT_LT(d.max, 1e-6);
    EXPECT_EQ(d.samples, 10000u);
}

TEST(Distance, KnownOffsetOfParallelPlanes) {
    // Unit square and the same square lifted by 0.25 and enlarged so no sample sees its border.
    Mesh a, b;
    a.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
    a.triangles = {{0, 1, 2}, {0, 2, 3}};
    b.points = {{-1, -1, 0.25f}, {2, -1, 0.25f}, {2, 2, 0.25f}, {-1, 2, 0.25f}};
    b.triangles = a.triangles;
    const DistanceStats d = sampleDistance(a, b, 1000, 5);
    EXPECT_DOUBLE_EQ(d.mean, 0.25);
    EXPECT_DOUBLE_EQ(d.rms, 0.25);
    EXPECT_DOUBLE_EQ(d.max, 0.25);
}

TEST(Distance, ZeroAreaComponentIsNoCorner) {
    // A = a unit square plus, 5 above it, a closed component of zero area (four faces on one point,
    // as Marching Cubes makes around a voxel exactly at the iso-value): it carries no surface, so
    // neither the area samples nor the vertex queries see it. One face of area moved there would.
    Mesh a, b;
    a.points = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {0.5f, 0.5f, 5}, {0.5f, 0.5f, 5}, {0.5f, 0.5f, 5}, {0.5f, 0.5f, 5}};
    a.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 7, 5}, {5, 7, 6}, {6, 7, 4}};
    b.points = {{-1, -1, 0.25f}, {2, -1, 0.25f}, {2, 2, 0.25f}, {-1, 2, 0.25f}};
    b.triangles = {{0, 1, 2}, {0, 2, 3}};
    const DistanceStats d = sampleDistance(a, b, 1000, 5);
    EXPECT_DOUBLE_EQ(d.max, 0.25);
    EXPECT_EQ(d.vertexQueries, 4u);
    a.points[6] = {0.6f, 0.5f, 5};
    a.points[7] = {0.5f, 0.6f, 5};
    const DistanceStats withArea = sampleDistance(a, b, 1000, 5);
    EXPECT_NEAR(withArea.max, 4.75, 1e-6);
    EXPECT_EQ(withArea.vertexQueries, 8u);
}

TEST(Distance, SamplingIsUniformByArea) {
    // A = two triangles, one with 3 times the area of the other, at different heights above B:
    // the mean is the area-weighted average of the heights.
    Mesh a, b;
    a.points = {{0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {0, 0, 2}, {3, 0, 2}, {0, 1, 2}};
    a.triangles = {{0, 1, 2}, {3, 4, 5}};
    b.points = {{-10, -10, 0}, {10, -10, 0}, {10, 10, 0}, {-10, 10, 0}};
    b.triangles = {{0, 1, 2}, {0, 2, 3}};
    const DistanceStats d = sampleDistance(a, b, 100000, 9);
    EXPECT_NEAR(d.mean, (1 * 1 + 3 * 2) / 4.0, 1e-4); // systematic sampling: error ~ 1 / samples
    EXPECT_NEAR(d.rms, std::sqrt((1 * 1 + 3 * 4) / 4.0), 1e-4);
    EXPECT_DOUBLE_EQ(d.max, 2.0);
}

TEST(Distance, IndependentOfThreadCountAndSeedStable) {
    const Mesh a = icosphere(5);
    Mesh b = icosphere(3); // coarser: a non-constant error field
    const DistanceStats parallel = sampleDistance(a, b, 200000, 42);
    DistanceStats serial;
    {
        tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
        serial = sampleDistance(a, b, 200000, 42);
    }
    EXPECT_EQ(parallel.mean, serial.mean); // bit-identical
    EXPECT_EQ(parallel.rms, serial.rms);
    EXPECT_EQ(parallel.max, serial.max);
    // A different seed moves the estimates by far less than 1%.
    const DistanceStats other = sampleDistance(a, b, 200000, 43);
    EXPECT_NE(other.mean, parallel.mean);
    EXPECT_NEAR(other.mean / parallel.mean, 1.0, 0.005);
    EXPECT_NEAR(other.rms / parallel.rms, 1.0, 0.005);
}

TEST(Distance, RejectsEmptyMeshes) {
    Mesh empty;
    EXPECT_THROW(sampleDistance(cube(), empty, 100, 1), std::invalid_argument);
    EXPECT_THROW(sampleDistance(empty, cube(), 100, 1), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// mesh files

TEST(MeshIO, RoundTripKeepsIndexArrays) {
    const Mesh m = icosphere(2);
    for (const char* ext : {"ply", "obj", "off"}) {
        const std::string path = tempPath(std::string("sphere.") + ext);
        writeMeshOpenMesh(m, path);
        const Mesh r = readMesh(path);
        std::filesystem::remove(path);
        EXPECT_EQ(r.points, m.points) << ext;
        EXPECT_EQ(r.triangles, m.triangles) << ext;
    }
}

TEST(MeshIO, RoundTripStl) {
    // STL has no shared vertices; the reader merges equal positions, so compare triangle corners.
    const Mesh m = icosphere(2);
    const std::string path = tempPath("sphere.stl");
    writeMeshOpenMesh(m, path);
    const Mesh r = readMesh(path);
    std::filesystem::remove(path);
    EXPECT_EQ(r.points.size(), m.points.size());
    ASSERT_EQ(r.triangles.size(), m.triangles.size());
    for (size_t f = 0; f < m.triangles.size(); ++f)
        for (size_t k = 0; k < 3; ++k) ASSERT_EQ(r.points[r.triangles[f][k]], m.points[m.triangles[f][k]]);
    EXPECT_TRUE(computeMeshStats(r).closed());
}

TEST(MeshIO, ReadKeepsNonManifoldTopology) {
    // Three triangles on one edge: OpenMesh's own importer would split one off.
    const std::string path = tempPath("fin.ply");
    std::ofstream(path) << "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
                           "property float z\nelement face 3\nproperty list uchar int vertex_indices\nend_header\n"
                           "0 0 0\n1 0 0\n0 1 0\n0 -1 0\n0 0 1\n3 0 1 2\n3 1 0 3\n3 1 0 4\n";
    const Mesh m = readMesh(path);
    std::filesystem::remove(path);
    EXPECT_EQ(m.points.size(), 5u);
    EXPECT_EQ(m.triangles.size(), 3u);
    EXPECT_EQ(computeMeshStats(m).nonManifoldEdges, 1u);
}

TEST(MeshIO, ObjPolygonsBecomeTriangleFans) {
    const std::string path = tempPath("quad.obj");
    std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n";
    const Mesh m = readMesh(path);
    std::filesystem::remove(path);
    ASSERT_EQ(m.triangles.size(), 2u);
    EXPECT_EQ(m.triangles[0], (std::array<uint32_t, 3>{0, 1, 2}));
    EXPECT_EQ(m.triangles[1], (std::array<uint32_t, 3>{0, 2, 3}));
}

TEST(MeshIO, ErrorsNameTheFile) {
    const std::string missing = tempPath("does_not_exist.ply");
    try {
        readMesh(missing);
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(missing), std::string::npos) << e.what();
    }
    const std::string garbage = tempPath("garbage.ply");
    std::ofstream(garbage) << "this is not a ply file\n";
    try {
        readMesh(garbage);
        FAIL() << "no exception";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(garbage), std::string::npos) << e.what();
    }
    std::filesystem::remove(garbage);
    const std::string badIndex = tempPath("bad_index.obj");
    std::ofstream(badIndex) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nf 1 2 9\n";
    EXPECT_THROW(readMesh(badIndex), std::runtime_error);
    std::filesystem::remove(badIndex);
}

TEST(MeshIO, OpenMeshConversionCountsRefusedFaces) {
    Mesh fin;
    fin.points = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}};
    fin.triangles = {{0, 1, 2}, {1, 0, 3}, {1, 0, 4}, {0, 0, 1}};
    size_t refused = 0;
    const TriMesh om = toOpenMesh(fin, refused);
    EXPECT_EQ(refused, 2u); // the third face on the edge, and the repeated index
    EXPECT_EQ(om.n_faces(), 2u);
    EXPECT_THROW(toOpenMesh(fin), std::runtime_error);
    EXPECT_THROW(decimateWithOpenMesh(fin, 1), std::runtime_error);
    const Mesh back = fromOpenMesh(toOpenMesh(cube()));
    EXPECT_EQ(back.points, cube().points);
    EXPECT_EQ(back.triangles, cube().triangles);
}

// ---------------------------------------------------------------------------------------------
// OpenMesh baseline

TEST(ReferenceDecimate, IcosphereToTenPercent) {
    const Mesh full = icosphere(6);
    const size_t target = full.triangles.size() / 10;
    const Mesh coarse = decimateWithOpenMesh(full, target);
    EXPECT_NEAR(double(coarse.triangles.size()), double(target), 0.01 * double(target));
    const MeshStats s = computeMeshStats(coarse);
    EXPECT_TRUE(s.closed());
    EXPECT_TRUE(s.manifold());
    EXPECT_TRUE(s.oriented());
    EXPECT_EQ(s.eulerCharacteristic, 2);
    EXPECT_EQ(s.components, 1u);
    EXPECT_EQ(s.zeroAreaFaces, 0u);
    // Still a good sphere: 8k faces approximate it within a fraction of a percent.
    const SymmetricDistance d = symmetricDistance(full, coarse, 100000, 1);
    EXPECT_LT(d.hausdorff, 0.01);
    EXPECT_GT(d.ab.mean, 0.0);
}
