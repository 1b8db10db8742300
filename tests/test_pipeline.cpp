// End to end through the library: R = 1 equals dense Marching Cubes; simplified meshes stay closed,
// manifold and outward; face targets are met; memory follows the paper's bound; threads don't matter;
// quality matches OpenMesh's in-core decimator.
#include "mesh_error.h"
#include "mesh_stats.h"
#include "reference_decimate.h"
#include "surface_checks.h"
#include "test_grids.h"
#include "test_volumes.h"
#include "pipeline/pipeline_internal.h"
#include "vdb/block_order.h"
#include "vdb_isosimp/errors.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <future>
#include <thread>
#include <functional>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <set>
#include <tuple>
#include <unistd.h>

using namespace vdb_isosimp;
namespace vt = vdb_isosimp::testing;
using vt::expectClosedOutward;

namespace {

// Matches the vertices of `a` and `b` by position (within tol) and compares the faces as cyclic index
// triples: the same surface with the same winding, independent of vertex and face order.
void expectSameMesh(const Mesh& a, const Mesh& b, double tol)
{
    ASSERT_EQ(a.points.size(), b.points.size());
    ASSERT_EQ(a.triangles.size(), b.triangles.size());
    std::multimap<std::tuple<long, long, long>, uint32_t> grid;
    auto cell = [tol](const std::array<float, 3>& p, int dx, int dy, int dz) {
        return std::make_tuple(long(std::floor(p[0] / (4 * tol))) + dx, long(std::floor(p[1] / (4 * tol))) + dy,
                               long(std::floor(p[2] / (4 * tol))) + dz);
    };
    for (uint32_t i = 0; i < b.points.size(); ++i) grid.emplace(cell(b.points[i], 0, 0, 0), i);
    // Coincident vertices (values exactly at the iso-value) match any of their twins; the faces decide.
    std::vector<uint32_t> map(a.points.size(), UINT32_MAX);
    std::vector<char> used(b.points.size(), 0);
    for (uint32_t i = 0; i < a.points.size(); ++i) {
        for (int d = 0; d < 27 && map[i] == UINT32_MAX; ++d) {
            auto range = grid.equal_range(cell(a.points[i], d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1));
            for (auto it = range.first; it != range.second; ++it) {
                const auto& q = b.points[it->second];
                if (!used[it->second] && std::abs(q[0] - a.points[i][0]) <= tol && std::abs(q[1] - a.points[i][1]) <= tol &&
                    std::abs(q[2] - a.points[i][2]) <= tol) {
                    map[i] = it->second;
                    used[it->second] = 1;
                    break;
                }
            }
        }
        ASSERT_NE(map[i], UINT32_MAX) << "vertex " << i << " has no counterpart";
    }
    // Coincident vertices of b form one class, named by its smallest index.
    std::vector<uint32_t> cls(b.points.size());
    for (uint32_t i = 0; i < b.points.size(); ++i) {
        cls[i] = i;
        for (int d = 0; d < 27; ++d) {
            auto range = grid.equal_range(cell(b.points[i], d % 3 - 1, (d / 3) % 3 - 1, d / 9 - 1));
            for (auto it = range.first; it != range.second; ++it) {
                const auto& q = b.points[it->second];
                if (std::abs(q[0] - b.points[i][0]) <= tol && std::abs(q[1] - b.points[i][1]) <= tol &&
                    std::abs(q[2] - b.points[i][2]) <= tol)
                    cls[i] = std::min(cls[i], it->second);
            }
        }
    }
    // Faces as cyclic triples of classes, rotated so the smallest comes first: keeps the winding.
    auto canonical = [&](uint32_t x, uint32_t y, uint32_t z) {
        std::array<uint32_t, 3> t{cls[x], cls[y], cls[z]};
        int m = 0;
        for (int k = 1; k < 3; ++k) if (t[k] < t[m]) m = k;
        return std::array<uint32_t, 3>{t[m], t[(m + 1) % 3], t[(m + 2) % 3]};
    };
    std::multiset<std::array<uint32_t, 3>> fa, fb;
    for (const auto& t : a.triangles) fa.insert(canonical(map[t[0]], map[t[1]], map[t[2]]));
    for (const auto& t : b.triangles) fb.insert(canonical(t[0], t[1], t[2]));
    EXPECT_TRUE(fa == fb) << "faces differ (topology or winding)";
}

Options ratioOptions(double r, int threads = 0)
{
    Options o;
    o.ratio = r;
    o.threads = threads;
    return o;
}

// A file this test process made, removed when the process exits.
struct ProcessFile {
    std::string path;
    ~ProcessFile()
    {
        if (!path.empty()) std::remove(path.c_str());
    }
};

std::string sphereFile()
{
    static ProcessFile file;
    std::string& path = file.path;
    if (path.empty()) {
        openvdb::initialize();
        // Radius 90 voxels: about 400k faces at full resolution.
        auto g = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(45.0f, openvdb::Vec3f(1, 2, 3), 0.5f);
        g->setName("sphere");
        // One file per process: ctest runs tests in parallel and OpenVDB maps input files.
        path = vt::writeGrid(g, "sphere90_" + std::to_string(::getpid()));
    }
    return path;
}

std::string noiseFile()
{
    static ProcessFile file;
    std::string& path = file.path;
    if (path.empty()) {
        path = ::testing::TempDir() + "/noise112_" + std::to_string(::getpid()) + ".vdb";
        const std::string cmd = std::string(MAKE_VOLUME_EXE) + " noise -n 112 -o " + path + " > /dev/null";
        EXPECT_EQ(std::system(cmd.c_str()), 0);
    }
    return path;
}


} // namespace

// Acceptance: R = 1 reproduces dense Marching Cubes on random sparse grids with tiles, leaf boundaries,
// both grid classes, anisotropic rotated transforms and mirrored transforms.
// The report's reason a decimation stopped: within 1 % of the face target (at least 2 faces: a closed
// surface's count is even) it was met; above it, an error bound or else the topology kept it there.
TEST(Pipeline, StopReasonNamesWhatKeptTheSurfaceAboveItsTarget)
{
    EXPECT_EQ(vdb_isosimp::stopReason(10, 8, false), "target");
    EXPECT_EQ(vdb_isosimp::stopReason(11, 8, false), "topology");
    EXPECT_EQ(vdb_isosimp::stopReason(1010, 1000, false), "target");
    EXPECT_EQ(vdb_isosimp::stopReason(1011, 1000, false), "topology");
    EXPECT_EQ(vdb_isosimp::stopReason(1011, 1000, true), "error bound");
    EXPECT_EQ(vdb_isosimp::stopReason(900, 1000, true), "target");
    EXPECT_EQ(vdb_isosimp::stopReason(778, 0, true), "error bound");  // a bound alone sets no face target
    EXPECT_EQ(vdb_isosimp::stopReason(4, 0, false), "topology");      // ... and may leave the least surface
}

TEST(Pipeline, RatioOneEqualsDenseMarchingCubes)
{
    int n = 0;
    for (bool levelSet : {true, false})
        for (bool mirrored : {false, true})
            for (unsigned seed : {1u, 2u, 3u}) {
                vt::GridSpec spec;
                spec.seed = seed + (levelSet ? 0 : 100);
                spec.levelSet = levelSet;
                spec.mirrored = mirrored;
                spec.anisotropic = seed != 3;
                spec.bigTile = seed == 2;
                auto grid = vt::randomSparseGrid(spec);
                const double iso = levelSet ? 0.0 : 0.5;
                const std::string path = vt::writeGrid(grid, "dense_eq_" + std::to_string(n++));
                const Mesh ref = vt::denseMarchingCubes(*grid, iso);
                SCOPED_TRACE(path);
                EXPECT_GT(ref.triangles.size(), 1000u);
                // One slab, and many small ones (bands of a few rows, seams through every layer).
                for (uint64_t perSlab : {Options{}.blocksPerSlab, uint64_t(8)}) {
                    Options o = ratioOptions(1.0);
                    o.iso = iso;
                    o.blocksPerSlab = perSlab;
                    Result r = simplifyFile(path, o);
                    SCOPED_TRACE(std::to_string(r.report.slabs) + " slabs");
                    if (perSlab == 8) {
                        EXPECT_GE(r.report.slabs, 8u);
                    }
                    EXPECT_EQ(r.report.unfinalizedAtEnd, 0u);
                    EXPECT_EQ(r.report.facesFull, ref.triangles.size());
                    expectSameMesh(r.mesh, ref, 1e-4);
                }
                // The dense surface is closed and outward (zero-area faces allowed at R = 1).
                expectClosedOutward(ref, true, "dense reference");
            }
}

// Acceptance: R = 1 reproduces dense Marching Cubes where voxels sit exactly at the iso-value too (a
// level-set box whose faces lie on voxel planes, integer data with an integer iso-value), which puts
// several vertices on one voxel corner and leaves zero-area faces in the full-resolution surface.
TEST(Pipeline, RatioOneEqualsDenseMarchingCubesAtExactIsoValues)
{
    for (const char* name : {"box", "ct-int"})
        for (bool rotated : {false, true}) {
            const volumes::TestVolume v = volumes::makeVolume(name, 40, rotated);
            Options o = ratioOptions(1.0);
            o.iso = v.iso;
            const Result r = simplifyGrid(*v.grid, o);
            const Mesh ref = vt::denseMarchingCubes(*v.grid, v.iso);
            SCOPED_TRACE(v.grid->getName());
            EXPECT_GT(ref.triangles.size(), 1000u);
            EXPECT_EQ(r.report.facesFull, ref.triangles.size());
            expectSameMesh(r.mesh, ref, 1e-4);
        }
}

TEST(Pipeline, ClosedManifoldOutwardAtEveryRatio)
{
    for (const std::string& file : {sphereFile(), noiseFile()})
        for (double r : {1.0, 0.2, 0.05, 0.01}) {
            Result res = simplifyFile(file, ratioOptions(r));
            const std::string what = file + " R=" + std::to_string(r);
            expectClosedOutward(res.mesh, r == 1.0, what);
            EXPECT_GE(res.report.facesFull, 100000u) << what;
            const double target = r * double(res.report.facesFull);
            // At R = 0.01 the noise surface (360 components, ~190 handles) is mostly closed components
            // already at their minimum: the target is met by removing the smallest ones, and only there.
            EXPECT_LE(std::abs(double(res.report.facesOut) - target), 0.02 * target) << what << " faces " << res.report.facesOut;
            if (file == sphereFile() || r >= 0.05) {
                EXPECT_EQ(res.report.componentsDropped, 0u) << what;
            }
            EXPECT_EQ(res.report.facesOut, res.mesh.triangles.size());
            // Memory: the intermediate mesh never exceeds R*F + B + uncontractible faces (+1%).
            const double bound = target + double(ratioOptions(r).batchFaces) + double(res.report.maxUncontractibleFaces);
            EXPECT_LE(double(res.report.maxIntermediateFaces), 1.01 * bound) << what;
        }
}

TEST(Pipeline, EveryJoinDecimatesWhenSlabsAreSmall)
{
    // Slabs of 32 blocks stay under their share of the batch, so none leaves its initial phase; every
    // node of the merge tree must still decimate when it joins, so the final pass starts within the
    // deferral room of its target, not at full resolution.
    Options o = ratioOptions(0.05);
    o.blocksPerSlab = 32;
    const Result r = simplifyFile(sphereFile(), o);
    ASSERT_GE(r.report.slabs, 16u);
    const auto last = std::find_if(r.report.trace.begin(), r.report.trace.end(),
                                   [&](const DecimationRecord& d) { return d.facesGenerated == r.report.facesFull; });
    ASSERT_NE(last, r.report.trace.end());
    std::printf("%zu slabs; the final pass starts at %llu faces for a target of %llu (%llu at full resolution)\n",
                size_t(r.report.slabs), (unsigned long long)last->facesBefore, (unsigned long long)r.report.facesTarget,
                (unsigned long long)r.report.facesFull);
    EXPECT_LE(last->facesBefore, r.report.facesTarget + o.batchFaces / 2);
    expectClosedOutward(r.mesh, false, "sphere, small slabs");
}

// The scale run's volume kind (make_volume gyroid-band: a narrow-band level set of the gyroid clipped to
// a box), small: closed and outward at full resolution and simplified, enclosing the same volume.
TEST(Pipeline, GyroidBandIsClosedAtFullResolutionAndSimplified)
{
    const std::string path = ::testing::TempDir() + "/gyroid_band96_" + std::to_string(::getpid()) + ".vdb";
    const std::string cmd = std::string(MAKE_VOLUME_EXE) + " gyroid-band -n 96 --period 24 -o " + path + " > /dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    const Result full = simplifyFile(path, ratioOptions(1.0));
    expectClosedOutward(full.mesh, true, "gyroid-band R=1");
    EXPECT_GE(full.report.facesFull, 50000u);
    const Result simple = simplifyFile(path, ratioOptions(0.05));
    expectClosedOutward(simple.mesh, false, "gyroid-band R=0.05");
    const double target = 0.05 * double(full.report.facesFull);
    EXPECT_LE(std::abs(double(simple.report.facesOut) - target), 0.02 * target) << simple.report.facesOut;
    const double vFull = eval::computeMeshStats(full.mesh).signedVolume;
    const double vSimple = eval::computeMeshStats(simple.mesh).signedVolume;
    EXPECT_NEAR(vSimple, vFull, 0.02 * vFull);
    std::remove(path.c_str());
}

TEST(Pipeline, AbsoluteFaceTarget)
{
    for (uint64_t n : {5000u, 40000u}) {
        Options o;
        o.targetFaces = n;
        Result res = simplifyFile(noiseFile(), o);
        EXPECT_LE(std::abs(double(res.report.facesOut) - double(n)), 0.02 * double(n)) << res.report.facesOut;
        expectClosedOutward(res.mesh, false, "faces " + std::to_string(n));
    }
}

// A face target counts the blocks before extracting any: the count reports its own progress, in
// order and up to 1, before the first block's, and a cancel there stops the run.
TEST(Pipeline, FaceCountReportsProgressAndCancels)
{
    struct Record : Progress {
        std::vector<double> counted;
        size_t updates = 0, updatesBeforeCountEnded = 0;
        bool stopCounting = false;
        bool update(double, uint64_t) override
        {
            ++updates;
            if (counted.empty() || counted.back() < 1.0) ++updatesBeforeCountEnded;
            return true;
        }
        bool counting(double fraction) override
        {
            counted.push_back(fraction);
            return !stopCounting;
        }
    };
    Options target;
    target.targetFaces = 5000;
    Record rec;
    simplifyFile(noiseFile(), target, &rec);
    ASSERT_FALSE(rec.counted.empty());
    EXPECT_TRUE(std::is_sorted(rec.counted.begin(), rec.counted.end()));
    EXPECT_GT(rec.counted.front(), 0.0);
    EXPECT_EQ(rec.counted.back(), 1.0);
    EXPECT_EQ(rec.updatesBeforeCountEnded, 0u);
    EXPECT_GT(rec.updates, 0u);

    Record ratio;
    simplifyFile(noiseFile(), ratioOptions(0.2, 0), &ratio);
    EXPECT_TRUE(ratio.counted.empty());

    Record stop;
    stop.stopCounting = true;
    EXPECT_THROW(simplifyFile(noiseFile(), target, &stop), Cancelled);
    EXPECT_EQ(stop.counted.size(), 1u);
    EXPECT_EQ(stop.updates, 0u);

    // A progress that knows nothing of the count hears (0, 0) during it, and can cancel there.
    struct UpdateOnly : Progress {
        std::vector<double> fractions;
        bool update(double fraction, uint64_t) override
        {
            fractions.push_back(fraction);
            return false;
        }
    } only;
    EXPECT_THROW(simplifyFile(noiseFile(), target, &only), Cancelled);
    ASSERT_EQ(only.fractions.size(), 1u);
    EXPECT_EQ(only.fractions.front(), 0.0);
}

TEST(Pipeline, AFaceTargetOnALargeVolumeCountsASample)
{
    // A gyroid of 4,913 blocks in 128 slabs of 38 (a run of blocks each): with countSampleRuns 32 the
    // count reads one run in four. The rate it gives lies above the exact one (the margin covers the
    // estimate's error), the final pass still meets the target, the report's full count is the exact
    // one, and the threads do not change the mesh. A sample of one run says nothing: every block is
    // counted then, and the mesh is the exact count's.
    const std::string path = ::testing::TempDir() + "/gyroid128_" + std::to_string(::getpid()) + ".vdb";
    ASSERT_EQ(std::system((std::string(MAKE_VOLUME_EXE) + " gyroid -n 128 -o " + path + " > /dev/null").c_str()), 0);
    const auto run = [&](uint64_t sampleRuns, int threads) {
        Options o;
        o.targetFaces = 20000;
        o.blocksPerSlab = 64;
        o.countSampleRuns = sampleRuns;
        o.threads = threads;
        return simplifyFile(path, o);
    };
    const Result exact = run(0, 0), sampled = run(32, 0), sampledOne = run(32, 1), coarse = run(1, 0);
    std::remove(path.c_str());
    EXPECT_EQ(exact.report.countStride, 1u);
    EXPECT_EQ(exact.report.countMargin, 0.0);
    EXPECT_EQ(sampled.report.countStride, 4u);
    EXPECT_GE(sampled.report.countMargin, 0.01);
    EXPECT_LE(sampled.report.countMargin, 0.1);
    std::printf("exact count %llu faces, R = %.5f; sampled (stride %llu, margin %.4f) R = %.5f\n",
                (unsigned long long)exact.report.facesFull, exact.report.ratio, (unsigned long long)sampled.report.countStride,
                sampled.report.countMargin, sampled.report.ratio);
    EXPECT_EQ(sampled.report.facesFull, exact.report.facesFull);
    EXPECT_GT(sampled.report.ratio, exact.report.ratio) << "the slabs keep at least the target between them";
    EXPECT_LT(sampled.report.ratio, 1.2 * exact.report.ratio);
    EXPECT_LE(std::abs(double(sampled.report.facesOut) - 20000.0), 0.02 * 20000.0) << sampled.report.facesOut;
    expectClosedOutward(sampled.mesh, false, "sampled count");
    const double vExact = eval::computeMeshStats(exact.mesh).signedVolume;
    EXPECT_NEAR(eval::computeMeshStats(sampled.mesh).signedVolume, vExact, 0.01 * std::abs(vExact));
    EXPECT_EQ(sampled.mesh.triangles, sampledOne.mesh.triangles);
    EXPECT_EQ(sampled.mesh.points, sampledOne.mesh.points);
    EXPECT_EQ(coarse.report.countStride, 1u);
    EXPECT_EQ(coarse.mesh.triangles, exact.mesh.triangles);
    EXPECT_EQ(coarse.mesh.points, exact.mesh.points);
}

TEST(Pipeline, AFaceTargetCountsOnTheVolumeItExtracts)
{
    // The count reads copies of the leaves and extraction follows on the same volume: one open (a
    // second one would read the topology again, on every MPI rank), the count equal to the faces
    // extraction makes, and the mesh of a run at the rate the count gives.
    const std::string path = noiseFile();
    int opens = 0;
    Options o;
    o.targetFaces = 20000;
    o.iso = 0.3;  // given: a default iso-value would scan a caller's grid in place first, loading it
    const Result counted = simplifyVolume(
        [&] {
            ++opens;
            return Volume::open(path, "");
        },
        path, o, nullptr);
    EXPECT_EQ(opens, 1);
    Options r = ratioOptions(double(o.targetFaces) / double(counted.report.facesFull));
    r.iso = o.iso;
    const Result rated = simplifyFile(path, r);
    EXPECT_EQ(counted.report.facesFull, rated.report.facesFull);
    EXPECT_EQ(counted.mesh.triangles, rated.mesh.triangles);
    EXPECT_EQ(counted.mesh.points, rated.mesh.points);
    EXPECT_NEAR(double(counted.mesh.triangles.size()), double(o.targetFaces), 0.01 * double(o.targetFaces));
    // A caller's grid read with delayed loading (leaves still on disk) is counted as it is extracted,
    // in place: the same mesh.
    openvdb::io::File file(path);
    file.open(/*delayLoad=*/true);
    const openvdb::GridBase::Ptr grid = file.readGrid(file.beginName().gridName());
    file.close();
    const auto floats = openvdb::gridPtrCast<openvdb::FloatGrid>(grid);
    ASSERT_TRUE(floats);
    size_t onDisk = 0;
    for (auto leaf = floats->tree().cbeginLeaf(); leaf; ++leaf) onDisk += leaf->buffer().isOutOfCore();
    EXPECT_GT(onDisk, 0u);
    const Result inPlace = simplifyGrid(*grid, o);
    EXPECT_EQ(inPlace.report.facesFull, counted.report.facesFull);
    EXPECT_EQ(inPlace.mesh.triangles, counted.mesh.triangles);
}

TEST(Pipeline, SameOutputForAnyThreadCount)
{
    // Many small slabs and batches: slabs and joins run in parallel and every one decimates.
    Options o1 = ratioOptions(0.05, 1), o2 = ratioOptions(0.05, 2);
    for (Options* o : {&o1, &o2}) {
        o->blocksPerSlab = 32;
        o->batchFaces = 1000;
    }
    const Result a = simplifyFile(noiseFile(), o1);
    const Result b = simplifyFile(noiseFile(), o2);
    EXPECT_GE(a.report.slabs, 16u);
    EXPECT_GE(a.report.decimations, 2 * a.report.slabs);
    ASSERT_EQ(a.mesh.triangles.size(), b.mesh.triangles.size());
    EXPECT_TRUE(a.mesh.points == b.mesh.points);
    EXPECT_TRUE(a.mesh.triangles == b.mesh.triangles);
    // The decimation's work is the same too, and every pop is accounted for.
    const Report &ra = a.report, &rb = b.report;
    EXPECT_EQ(ra.queuePops, rb.queuePops);
    EXPECT_EQ(ra.queueDead, rb.queueDead);
    EXPECT_EQ(ra.queueStale, rb.queueStale);
    EXPECT_EQ(ra.collapseAttempts, rb.collapseAttempts);
    EXPECT_EQ(ra.collapses, rb.collapses);
    EXPECT_EQ(ra.queuePops, ra.queueDead + ra.queueStale + ra.collapseAttempts);
    EXPECT_LE(ra.collapses, ra.collapseAttempts);
    // A counted collapse removes two faces; the zero-area clean-up removes a few more uncounted.
    EXPECT_GT(ra.collapses, 0u);
    EXPECT_LE(2 * ra.collapses, ra.facesFull - ra.facesOut);
}

// A thread count limits one run, not the process: while a run with threads = 1 is under way inside
// an arena of 2 (held at its first progress report), another arena of 2 still gets two threads
// working at once. A process-wide limit (tbb::global_control) would leave that arena one thread.
TEST(Pipeline, ThreadCountLimitsTheRunOnly)
{
    struct Hold : Progress {
        std::promise<void> started;
        std::shared_future<void> release;
        bool first = true;
        bool update(double, uint64_t) override
        {
            if (first) {
                first = false;
                started.set_value();
                release.wait();
            }
            return true;
        }
    } hold;
    std::promise<void> releaseRun;
    hold.release = releaseRun.get_future().share();
    std::future<void> started = hold.started.get_future();
    std::thread run([&] {
        tbb::task_arena outer(2);
        outer.execute([&] { simplifyFile(sphereFile(), ratioOptions(0.2, 1), &hold); });
    });
    ASSERT_EQ(started.wait_for(std::chrono::seconds(60)), std::future_status::ready);

    tbb::task_arena other(2);
    std::atomic<int> inside{0};
    std::atomic<bool> together{false};
    other.execute([&] {
        EXPECT_EQ(tbb::this_task_arena::max_concurrency(), 2);
        tbb::parallel_for(tbb::blocked_range<int>(0, 2, 1), [&](const tbb::blocked_range<int>&) {
            ++inside;
            // Both halves in flight at once, or 5 s pass.
            const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
            while (inside.load() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
            if (inside.load() == 2) together = true;
        });
    });
    releaseRun.set_value();
    run.join();
    EXPECT_TRUE(together.load()) << "another arena ran on one thread while a threads = 1 run was under way";
}

// Acceptance on organic volumes (a sphere, CT-like noise, integer CT-like data with many voxels exactly
// at the iso-value): the RMS distance from the full-resolution surface to ours is at most that of
// extracting everything and running OpenMesh's DecimaterT + ModQuadricT to the same face count, and
// the symmetric Hausdorff distance at most 1.25x OpenMesh's + 0.01 % of the diagonal.
TEST(Pipeline, QualityMatchesOpenMeshDecimater)
{
    struct Input {
        std::string name;
        std::function<Result(const Options&)> simplify;
    };
    const volumes::TestVolume ct = volumes::makeVolume("ct-int", 96);
    const std::vector<Input> inputs{
        {sphereFile(), [](const Options& o) { return simplifyFile(sphereFile(), o); }},
        {noiseFile(), [](const Options& o) { return simplifyFile(noiseFile(), o); }},
        {"ct-int 96^3", [&](Options o) { o.iso = ct.iso; return simplifyGrid(*ct.grid, o); }},
    };
    for (const Input& in : inputs) {
        const Mesh full = in.simplify(ratioOptions(1.0)).mesh;
        for (double r : {0.2, 0.02}) {
            const Result ours = in.simplify(ratioOptions(r));
            expectClosedOutward(ours.mesh, false, in.name + " R=" + std::to_string(r));
            const Mesh theirs = eval::decimateWithOpenMesh(full, ours.mesh.triangles.size());
            // Where OpenMesh stops above our face count, both are compared at its count.
            const Mesh oursAtTheirs = theirs.triangles.size() > ours.mesh.triangles.size() + 2
                ? [&] { Options o = ratioOptions(1.0); o.targetFaces = theirs.triangles.size(); return in.simplify(o).mesh; }()
                : ours.mesh;
            const eval::SurfaceError eOurs = eval::surfaceError(full, oursAtTheirs, 400000);
            const eval::SurfaceError eTheirs = eval::surfaceError(full, theirs, 400000);
            std::printf("[quality] %s R=%.2f faces ours %zu openmesh %zu  RMS %% of diagonal: ours %.5f openmesh %.5f  ratio %.3f"
                        "  Hausdorff %%: ours %.4f openmesh %.4f\n",
                        in.name.c_str(), r, oursAtTheirs.triangles.size(), theirs.triangles.size(), eOurs.rmsPct, eTheirs.rmsPct,
                        eOurs.rmsPct / eTheirs.rmsPct, eOurs.hausdorffPct, eTheirs.hausdorffPct);
            EXPECT_LE(eOurs.rmsPct, eTheirs.rmsPct) << in.name << " R=" << r;
            EXPECT_LE(eOurs.hausdorffPct, 1.25 * eTheirs.hausdorffPct + 0.01) << in.name << " R=" << r;
        }
    }
}

TEST(Pipeline, MemoryBudgetIsCheckedOnTheOpenedGrid)
{
    Options o = ratioOptions(0.2);
    o.maxMemoryBytes = 1 << 20;  // below the fixed base of the estimate: always refused
    try {
        simplifyFile(sphereFile(), o);
        ADD_FAILURE() << "a 1 MiB budget was accepted";
    } catch (const InputError& e) {
        const std::string what = e.what();
        EXPECT_EQ(what.rfind(sphereFile() + ": estimated peak memory", 0), 0u) << what;
    }
    o.maxMemoryBytes = 64ull << 30;
    EXPECT_GT(simplifyFile(sphereFile(), o).report.facesOut, 0u);
}

// A grid of tiles only: its leaves say nothing of the surface its tiles' faces describe.
TEST(Pipeline, MemoryBudgetCountsTheSurfaceAlongTileFaces)
{
    Options o = ratioOptions(0.2);
    o.iso = 0.5;
    o.maxMemoryBytes = 4ull << 30;
    // One root tile, 4096^3 voxels: 6 x 513^2 shell blocks, some 200M faces at full resolution.
    const auto huge = openvdb::FloatGrid::create(0.0f);
    huge->tree().addTile(3, openvdb::Coord(0), 1.0f, true);
    try {
        simplifyGrid(*huge, o);
        ADD_FAILURE() << "a 4096^3 tile's surface was accepted within 4 GiB";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("1579014 blocks along tile faces"), std::string::npos) << e.what();
    }
    // One 128^3 tile (6 x 17^2 shell blocks) fits: the count bounds the block list and the surface.
    const auto box = openvdb::FloatGrid::create(0.0f);
    box->tree().addTile(2, openvdb::Coord(0), 1.0f, true);
    Classifier c;
    c.iso = 0.5;
    EXPECT_EQ(countTileShellBlocks(box->tree(), c), 6u * 17 * 17);
    o.ratio = 1.0;
    const Result r = simplifyGrid(*box, o);
    EXPECT_LE(r.report.blocks, 6u * 17 * 17);
    EXPECT_NEAR(double(r.report.facesOut) / (128.0 * 6 * 17 * 17), 1.0, 0.15);  // the estimate's faces per block
}

// Tiles only, none crossing the iso-value: no block at all to extract, which is "no surface".
TEST(Pipeline, TilesWithoutSurfaceAreNoSurface)
{
    const auto grid = openvdb::FloatGrid::create(0.0f);
    grid->tree().addTile(2, openvdb::Coord(0), 1.0f, true);
    for (uint64_t faces : {uint64_t(0), uint64_t(100)}) {
        Options o;
        o.iso = 5.0;
        o.targetFaces = faces;
        try {
            simplifyGrid(*grid, o);
            ADD_FAILURE() << "meshed a surface at iso 5 in values [0, 1]";
        } catch (const EmptySurfaceError& e) {
            EXPECT_NE(std::string(e.what()).find("no surface at iso-value 5"), std::string::npos) << e.what();
        }
    }
}

TEST(Pipeline, BadOptionsAreRejected)
{
    EXPECT_THROW(simplifyFile(sphereFile(), ratioOptions(0.0)), InputError);
    EXPECT_THROW(simplifyFile(sphereFile(), ratioOptions(1.5)), InputError);
    Options o;
    o.iso = 100.0;
    EXPECT_THROW(simplifyFile(sphereFile(), o), EmptySurfaceError);
}
