// The decimation schedule (schedule.h, the paper's section 4.2 with deferral room), driven directly with
// the block meshes of a sphere level set, against the contract it states: before the final pass, a pass
// runs at the latest every B/2 new faces and stops at F_t + B/2, F_t = (F_g - F_u) R + F_u; so after a
// pass that reached its target the mesh never holds more than that F_t + B faces before the next; the
// final pass reaches its target.
#include "core/schedule.h"
#include "vdb/volume_reader.h"

#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>

using namespace vdb_isosimp;

namespace {

// The sphere's block meshes in block order, as the pipeline extracts them (one slab).
std::vector<BlockMesh> sphereBlocks(float radius)
{
    openvdb::initialize();
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(radius, openvdb::Vec3f(0.5f, 1.5f, 2.5f), 1.0f);
    const auto vol = Volume::fromGrid(grid, "sphere");
    Classifier cls;
    cls.insideBelow = true;
    cls.iso = 0.0;
    std::vector<BlockMesh> meshes;
    for (const auto& origin : vol->blocks(cls)) {
        BlockSamples s;
        vol->sample(origin, s);
        meshes.emplace_back();
        extractBlock(s, cls, vol->info().indexToWorld, false, meshes.back());
    }
    return meshes;
}

uint64_t regularTarget(const DecimationRecord& r, double ratio)
{
    const double fu = double(r.uncontractible);
    return uint64_t(std::max(0.0, double(r.facesGenerated) - fu) * ratio + fu);
}

} // namespace

TEST(Schedule, PassesEveryHalfBatchToTheTargetPlusDeferral)
{
    const std::vector<BlockMesh> blocks = sphereBlocks(40.0f);
    for (const uint64_t batch : {2000u, 5000u}) {
        for (const double ratio : {0.2, 0.05}) {
            Options o;
            o.initialRatio = 0.01;  // below R: no initial phase, the regular schedule from the first batch
            Integrator integ(o, ratio, batch, 0);
            uint64_t generated = 0, largestBlock = 0;
            for (const BlockMesh& b : blocks) {
                integ.add(b);
                generated += b.triangles.size();
                largestBlock = std::max<uint64_t>(largestBlock, b.triangles.size());
            }
            integ.finishSlab();
            ASSERT_EQ(integ.facesGenerated(), generated);
            ASSERT_GT(generated, 10 * batch) << "too few faces to exercise the schedule";
            const SlabStats stats = integ.stats();
            const std::vector<DecimationRecord>& trace = stats.trace;
            ASSERT_GE(trace.size(), generated / batch);
            uint64_t previous = 0;
            size_t reached = 0;
            for (size_t i = 0; i < trace.size(); ++i) {
                const DecimationRecord& r = trace[i];
                const std::string what = "B=" + std::to_string(batch) + " R=" + std::to_string(ratio) + " pass " + std::to_string(i);
                EXPECT_EQ(r.target, regularTarget(r, ratio) + batch / 2) << what;
                EXPECT_LE(r.facesGenerated - previous, batch / 2) << what;
                EXPECT_LE(r.facesAfter, std::max(r.target, r.uncontractible + largestBlock)) << what;
                if (i > 0 && trace[i - 1].facesAfter <= trace[i - 1].target) {
                    // F_t + B of the previous pass, whose F_t is F_t(prev) + B/2 with B/2 faces added since.
                    EXPECT_LE(r.facesBefore, trace[i - 1].target + batch / 2) << what;
                    ++reached;
                }
                previous = r.facesGenerated;
            }
            EXPECT_GT(reached, trace.size() / 2) << "most passes reach their target";
            EXPECT_EQ(previous, generated) << "the slab's last batch is decimated by finishSlab";

            uint64_t unfinalized = 0;
            const uint64_t target = uint64_t(std::llround(ratio * double(generated)));
            integ.finish(target, generated, unfinalized);
            // A collapse removes two faces: the final count lands on the target or one below.
            EXPECT_LE(integ.decimator().faceCount(), target);
            EXPECT_GE(integ.decimator().faceCount() + 1, target);
        }
    }
}
