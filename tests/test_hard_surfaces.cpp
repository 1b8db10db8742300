// Fidelity on hard surfaces (issue: flat faces and sharp edges stay exact, voxels at the iso-value
// leave no slivers): every volume of test_volumes.h, as OpenVDB's tools build them, at several ratios
// and batch sizes, against OpenMesh's decimator on the same full-resolution surface at our face count.
#include "mesh_error.h"
#include "mesh_stats.h"
#include "reference_decimate.h"
#include "surface_checks.h"
#include "test_volumes.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>

using namespace vdb_isosimp;

namespace {

constexpr int kSize = 64;  // voxels across each solid: 14k to 42k faces at full resolution

Result run(const volumes::TestVolume& v, double ratio, uint64_t batch = Options{}.batchFaces, int threads = 0,
           uint64_t blocksPerSlab = Options{}.blocksPerSlab, uint64_t retireAbove = Options{}.retireAboveFaces)
{
    Options o;
    o.retireAboveFaces = retireAbove;
    o.blocksPerSlab = blocksPerSlab;
    o.ratio = ratio;
    o.iso = v.iso;
    o.batchFaces = batch;
    o.threads = threads;
    return simplifyGrid(*v.grid, o);
}

class HardSurface : public ::testing::TestWithParam<std::tuple<std::string, bool>> {};

// Acceptance 1: symmetric Hausdorff <= max(1.1 x OpenMesh's, 0.02 % of the diagonal), RMS <= max(1.1 x
// OpenMesh's, 0.002 %), at R in {0.5, 0.2, 0.05} and B in {1000, default}; the output is a clean surface.
TEST_P(HardSurface, AsExactAsOpenMeshAtEveryRatioAndBatch)
{
    const auto& [name, rotated] = GetParam();
    const volumes::TestVolume v = volumes::makeVolume(name, kSize, rotated);
    const Mesh full = run(v, 1.0).mesh;
    for (double r : {0.5, 0.2, 0.05})
        for (uint64_t b : {uint64_t(1000), Options{}.batchFaces}) {
            const Mesh ours = run(v, r, b).mesh;
            const std::string what = v.grid->getName() + " R=" + std::to_string(r) + " B=" + std::to_string(b);
            vdb_isosimp::testing::expectClosedOutward(ours, false, what);
            const eval::SurfaceError e = eval::surfaceError(full, ours, 200000);
            const eval::SurfaceError om = eval::surfaceError(full, eval::decimateWithOpenMesh(full, ours.triangles.size()), 200000);
            std::printf("[fidelity] %s faces %zu -> %zu  RMS %% ours %.5f openmesh %.5f  Hausdorff %% ours %.4f openmesh %.4f\n",
                        what.c_str(), full.triangles.size(), ours.triangles.size(), e.rmsPct, om.rmsPct, e.hausdorffPct,
                        om.hausdorffPct);
            EXPECT_LE(e.hausdorffPct, std::max(1.1 * om.hausdorffPct, 0.02)) << what;
            EXPECT_LE(e.rmsPct, std::max(1.1 * om.rmsPct, 0.002)) << what;
        }
}

INSTANTIATE_TEST_SUITE_P(Volumes, HardSurface,
                         ::testing::Combine(::testing::ValuesIn(volumes::hardSurfaceNames()), ::testing::Bool()),
                         [](const auto& info) {
                             std::string n = std::get<0>(info.param) + (std::get<1>(info.param) ? "_rotated" : "");
                             std::replace(n.begin(), n.end(), '-', '_');
                             return n;
                         });

// Acceptance 3 and 4 on integer data with the iso-value on an integer (many voxels exactly at it):
// no zero-area face below R = 1, closed and outward, the same bytes for any thread count; also cut
// into many slabs (16 blocks each), so seams run through coincident vertices and join in the tree.
TEST(ExactIso, IntegerVolumeLeavesNoSliversAndIgnoresThreadCount)
{
    for (bool rotated : {false, true}) {
        const volumes::TestVolume v = volumes::makeVolume("ct-int", kSize, rotated);
        for (uint64_t perSlab : {Options{}.blocksPerSlab, uint64_t(16)})
            for (double r : {0.5, 0.2, 0.05}) {
                const Result one = run(v, r, 1000, 1, perSlab), two = run(v, r, 1000, 2, perSlab);
                const std::string what = v.grid->getName() + " R=" + std::to_string(r) + " slabs " + std::to_string(one.report.slabs);
                if (perSlab == 16) {
                    EXPECT_GE(one.report.slabs, 16u) << what;
                }
                vdb_isosimp::testing::expectClosedOutward(one.mesh, false, what);
                EXPECT_TRUE(one.mesh.points == two.mesh.points && one.mesh.triangles == two.mesh.triangles) << what;
            }
    }
}

TEST(ExactIso, BoxOnVoxelPlanesIgnoresThreadCount)
{
    const volumes::TestVolume v = volumes::makeVolume("box", kSize, false);
    for (double r : {0.5, 0.05}) {
        const Result one = run(v, r, 1000, 1, 16), two = run(v, r, 1000, 2, 16);
        EXPECT_GE(one.report.slabs, 16u);
        vdb_isosimp::testing::expectClosedOutward(one.mesh, false, "box R=" + std::to_string(r));
        EXPECT_TRUE(one.mesh.points == two.mesh.points && one.mesh.triangles == two.mesh.triangles) << r;
    }
}

// Retired interiors (Options::retireAboveFaces), forced low so that the joins of nodes above 1000
// faces retire (a fifth to a ninth of these outputs, as 100000 is of a large run's), in 16-block
// slabs: on every hard volume, and the integer one with voxels at the iso-value, the surface holds the
// same bounds against OpenMesh as above, stays clean, keeps its face target and is the same for any
// thread count. (Far lower, near the output's own size, the passes without room cut sharp edges: csg
// rotated at R = 0.05 with nodes of 500 faces, RMS 0.0072 % against OpenMesh's 0.0017 %.)
TEST(RetiredInterior, HardContentStaysExactCleanAndThreadIndependent)
{
    std::vector<std::string> names = volumes::hardSurfaceNames();
    names.push_back("ct-int");
    for (const std::string& name : names)
        for (bool rotated : {false, true}) {
            const volumes::TestVolume v = volumes::makeVolume(name, kSize, rotated);
            const Mesh full = run(v, 1.0).mesh;
            for (double r : {0.2}) {
                const Result one = run(v, r, 1000, 1, 16, 1000), two = run(v, r, 1000, 2, 16, 1000);
                const std::string what = v.grid->getName() + " R=" + std::to_string(r);
                EXPECT_GT(one.report.facesRetired, 0u) << what;
                vdb_isosimp::testing::expectClosedOutward(one.mesh, false, what);
                EXPECT_TRUE(one.mesh.points == two.mesh.points && one.mesh.triangles == two.mesh.triangles) << what;
                EXPECT_LE(double(one.report.facesOut), 1.01 * double(one.report.facesTarget)) << what;
                const eval::SurfaceError e = eval::surfaceError(full, one.mesh, 200000);
                const eval::SurfaceError om =
                    eval::surfaceError(full, eval::decimateWithOpenMesh(full, one.mesh.triangles.size()), 200000);
                std::printf("[retired] %s faces %zu -> %zu (%llu retired)  RMS %% ours %.5f openmesh %.5f  Hausdorff %% ours %.4f "
                            "openmesh %.4f\n",
                            what.c_str(), full.triangles.size(), one.mesh.triangles.size(),
                            (unsigned long long)one.report.facesRetired, e.rmsPct, om.rmsPct, e.hausdorffPct, om.hausdorffPct);
                EXPECT_LE(e.hausdorffPct, std::max(1.1 * om.hausdorffPct, 0.02)) << what;
                EXPECT_LE(e.rmsPct, std::max(1.1 * om.rmsPct, 0.002)) << what;
            }
        }
}

// A noise fog is mostly small closed components at low rates: the final pass drops the smallest until
// the face target holds, retired ones as live ones. (Retired components used to stay, and noise 128^3
// at R = 0.005 in 16-block slabs with nodes of 2,000 faces retiring stopped at 2,008 faces for a target
// of 1,592, where the same run without retiring reaches it.)
TEST(RetiredInterior, ComponentsStillGoWhereTheTargetNeedsIt)
{
    const openvdb::FloatGrid::Ptr grid = volumes::noiseFog(128, 1);
    for (double r : {0.01, 0.005}) {
        const std::string what = "noise 128^3 R=" + std::to_string(r);
        Options o;
        o.ratio = r;
        o.iso = 0.3;
        o.blocksPerSlab = 16;
        o.retireAboveFaces = 0;
        const Result live = simplifyGrid(*grid, o);
        o.retireAboveFaces = 2000;
        o.threads = 1;
        const Result one = simplifyGrid(*grid, o);
        o.threads = 2;
        const Result two = simplifyGrid(*grid, o);
        std::printf("[retired] %s: target %llu, %llu faces (%llu retired, %llu components dropped); without retiring %llu "
                    "(%llu dropped)\n",
                    what.c_str(), (unsigned long long)one.report.facesTarget, (unsigned long long)one.report.facesOut,
                    (unsigned long long)one.report.facesRetired, (unsigned long long)one.report.componentsDropped,
                    (unsigned long long)live.report.facesOut, (unsigned long long)live.report.componentsDropped);
        EXPECT_EQ(live.report.stoppedBy, "target") << what;
        EXPECT_GT(one.report.facesRetired, 0u) << what;
        EXPECT_GT(one.report.componentsDropped, 0u) << what;
        EXPECT_EQ(one.report.stoppedBy, "target") << what;
        EXPECT_LE(double(one.report.facesOut), 1.01 * double(one.report.facesTarget)) << what;
        vdb_isosimp::testing::expectClosedOutward(one.mesh, false, what);
        EXPECT_EQ(eval::computeMeshStats(one.mesh).referencedVertices, one.mesh.points.size()) << what;
        EXPECT_TRUE(one.mesh.points == two.mesh.points && one.mesh.triangles == two.mesh.triangles) << what;
    }
}

} // namespace
