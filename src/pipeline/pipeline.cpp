// The driver: a script of named stages (runPipeline).
//   open (delayed loading) -> iso-value -> block list (z/y/x) -> [count faces, for a face target]
//   -> slabs: extract blocks (parallel), integrate in order + decimate every B faces, join in order
//   -> final decimation.
#include "vdb_isosimp/vdb_isosimp.h"

#include "core/decimator.h"
#include "core/edge_key.h"
#include "core/marching_cubes.h"
#include "core/schedule.h"
#include "pipeline/levels.h"
#include "pipeline/memory_budget.h"
#include "pipeline/pipeline_internal.h"
#include "pipeline/run_stats.h"
#include "pipeline/slabs.h"
#include "vdb/attribute_sampler.h"
#include "vdb/block_order.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/errors.h"

#include <tbb/task_arena.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/blocked_range.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include <malloc.h>

namespace vdb_isosimp {

namespace {

void checkOptions(const Options& o)
{
    if (!(o.maxError >= 0.0 && o.maxError < HUGE_VAL)) {
        std::ostringstream s;
        s << "maximum error must be a finite number >= 0, got " << o.maxError;
        throw InputError(s.str());
    }
    checkLods(o);
    // Ratio 0 is no face target: the error bound alone decides.
    const bool errorAlone = o.ratio == 0.0 && o.maxError > 0.0;
    if (!errorAlone && !(o.ratio > 0.0 && o.ratio <= 1.0)) {
        std::ostringstream s;
        s << "ratio must be in (0, 1], got " << o.ratio;
        throw InputError(s.str());
    }
    if (o.batchFaces < 1000) throw InputError("batch must be at least 1000 faces");
    if (!(o.attributeWeight >= 0.0 && o.attributeWeight < HUGE_VAL)) throw InputError("attribute weight must be finite and >= 0");
    if (!(o.initialRatio > 0.0 && o.initialRatio <= 1.0)) throw InputError("initial ratio must be in (0, 1]");
    if (o.threads < 0) throw InputError("threads must be >= 0");
    if (o.iso && !std::isfinite(*o.iso)) throw InputError("iso-value must be finite");
}

// First stage of the pipelines below: next, next + 1, ... up to end (exclusive), in order. The counter
// lives with the caller: TBB calls stage bodies as const.
tbb::filter<void, size_t> indices(size_t& next, size_t end)
{
    return tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order, [&next, end](tbb::flow_control& fc) -> size_t {
        if (next == end) {
            fc.stop();
            return 0;
        }
        return next++;
    });
}

// Exact face count of the full-resolution surface: the same case table over the same blocks. It runs
// on its own delayed-loading copy of the grid and frees each leaf once its last block is counted
// (blocks in order, as in extraction), so counting does not load the whole volume at once.
uint64_t countFaces(Volume& vol, const std::vector<BlockOrigin>& blocks, const Classifier& cls)
{
    uint64_t total = 0;
    size_t next = 0;
    tbb::parallel_pipeline(
        4 * std::max<size_t>(1, std::thread::hardware_concurrency()),
        indices(next, blocks.size()) &
            tbb::make_filter<size_t, std::pair<size_t, uint64_t>>(tbb::filter_mode::parallel,
                                                                  [&](size_t i) {
                                                                      BlockSamples s;
                                                                      vol.sample(blocks[i], s);
                                                                      return std::make_pair(i, countBlockTriangles(s, cls));
                                                                  }) &
            tbb::make_filter<std::pair<size_t, uint64_t>, void>(tbb::filter_mode::serial_in_order,
                                                                [&](std::pair<size_t, uint64_t> r) {
                                                                    total += r.second;
                                                                    vol.releaseLeaf(blocks[r.first]);
                                                                    if (r.first % Volume::kTrimEveryBlocks == 0) vol.trimInputMapping();
                                                                }));
    return total;
}

// One run of the pipeline over one volume: the stages in the order runPipeline calls them, and the
// state they hand on.
class PipelineRun {
public:
    PipelineRun(const std::string& path, const Options& opt, Progress* progress)
        : mPath(path), mOpt(opt), mProgress(progress)
    {
    }

    void openVolume(const VolumeOpener& open);
    void chooseIso();
    void listBlocks();
    void setTarget(const VolumeOpener& open);
    void runSlabs();
    Result finalPass();

private:
    void extractSlab(size_t si);
    void meshBlock(size_t si, size_t i, BlockMesh& m) const;
    void integrateBlock(Integrator& integ, size_t si, const BlockMesh& m);
    EmptySurfaceError noSurface() const;

    static constexpr size_t kMallocTrimEveryBlocks = 4096;
    static constexpr size_t kProgressEveryBlocks = 256;

    const std::string& mPath;
    const Options& mOpt;
    Progress* mProgress;
    Stopwatch mClock;
    Result mResult;
    std::unique_ptr<Volume> mVol;
    std::unique_ptr<AttributeSampler> mAttributes;  // Options::attributes, checked at open
    VolumeInfo mInfo;  // a copy: the volume is opened again after counting
    Classifier mCls;
    bool mFlip = false;
    std::vector<BlockOrigin> mBlocks;
    double mRatio = 0.0;
    std::vector<Slab> mSlabs;
    std::vector<std::unique_ptr<Integrator>> mIntegs;
    // Range of the values sampled so far; voxel buffers are released as blocks finish, so the grid
    // itself can no longer be asked once extraction has run.
    std::array<double, 2> mSampled{0.0, 0.0};
    bool mReleased = false;
    std::mutex mProgressMutex;  // guards mSampled, mDone and the progress object
    size_t mDone = 0;
};

void PipelineRun::openVolume(const VolumeOpener& open)
{
    mVol = open();
    mInfo = mVol->info();
    // Attribute grids are checked now, before any voxel is read; they are read after the final pass.
    mAttributes = std::make_unique<AttributeSampler>(mInfo.file, mOpt.attributes);
    // A weighted attribute is sampled at every vertex as blocks are extracted: its grid is read now.
    if (mOpt.attributeWeight > 0) {
        if (mOpt.attributes.empty()) throw InputError("an attribute weight needs an attribute grid");
        if (!mAttributes->firstIsScalar())
            throw InputError(mInfo.file + ": grid '" + mOpt.attributes.front() +
                             "' is a vector grid; an attribute weight takes a float or double grid");
        mAttributes->load();
    }
    // On this open, not one of its own: reading the topology of a large file takes a while.
    if (mOpt.maxMemoryBytes > 0) checkMemoryBudget(mPath, mInfo, mOpt, mOpt.maxMemoryBytes);
    Report& rep = mResult.report;
    rep.file = mPath;
    rep.grid = mInfo.gridName;
    rep.valueType = mInfo.valueType;
    rep.gridClass = mInfo.levelSet ? "level set" : "fog";
    // A mirroring transform reverses the winding; compensate so normals still point outward.
    mFlip = mInfo.indexToWorld.determinant() < 0;
    mSampled = {mInfo.background, mInfo.background};
}

void PipelineRun::chooseIso()
{
    mCls.insideBelow = mInfo.levelSet;
    if (mOpt.iso) {
        mCls.iso = *mOpt.iso;
    } else if (mInfo.levelSet) {
        mCls.iso = 0.0;
    } else {
        const auto range = mVol->valueRange();
        mCls.iso = 0.5 * (range[0] + range[1]);
        mResult.report.isoDefaulted = true;
    }
    mResult.report.iso = mCls.iso;
}

void PipelineRun::listBlocks()
{
    // Blocks along tile faces are known once the iso-value is: a few large tiles can describe a
    // surface far larger than their leaves suggest, so the budget is checked again before listing them.
    if (mOpt.maxMemoryBytes > 0)
        if (const uint64_t shells = mVol->tileShellBlocks(mCls))
            checkMemoryBudget(mPath, mInfo, mOpt, mOpt.maxMemoryBytes, shells);
    mBlocks = mVol->blocks(mCls);
    mResult.report.blocks = mBlocks.size();
    if (mBlocks.empty()) throw noSurface();
}

void PipelineRun::setTarget(const VolumeOpener& open)
{
    // A LOD chain is extracted at its finest rate; the final pass makes the coarser levels from it.
    mRatio = mOpt.lods.empty() ? mOpt.ratio : mOpt.lods.front();
    if (mOpt.targetFaces == 0) return;
    // Counted on the volume itself, which frees leaves as it goes, then opened again for extraction:
    // one copy of the topology at a time (a second copy made the start of a run its peak on large
    // inputs kept to small outputs).
    Report& rep = mResult.report;
    rep.facesFull = countFaces(*mVol, mBlocks, mCls);
    mVol.reset();
    malloc_trim(0);
    mVol = open();
    if (rep.facesFull == 0) throw noSurface();
    mRatio = std::min(1.0, double(mOpt.targetFaces) / double(rep.facesFull));
}

// Slabs: whole block layers, each extracted and decimated on its own, in parallel when threads allow.
// Vertices on the x/y edges of a slab's first voxel layer are shared with the slab below, so they stay
// open there (a seam) until the slabs are merged; every other vertex follows the modifiability rule
// inside its slab. Each slab gets B/S faces per batch, so the intermediate meshes together stay within
// R*F + B plus the uncontractible faces.
void PipelineRun::runSlabs()
{
    mSlabs = splitSlabs(mBlocks, kPipelineSlabs);
    const uint64_t batch = std::max<uint64_t>(1000, mOpt.batchFaces / mSlabs.size());
    for (uint32_t i = 0; i < mSlabs.size(); ++i) mIntegs.push_back(std::make_unique<Integrator>(mOpt, mRatio, batch, i));
    // The decimator's least face weight is a fraction of a voxel face, in world units.
    const double voxelArea = std::pow(std::abs(mInfo.indexToWorld.determinant()), 2.0 / 3.0);
    for (auto& integ : mIntegs) integ->decimator().setVoxelArea(voxelArea);
    mReleased = true;
    // Decimation passes poll the same progress object, so a cancel request stops them too.
    if (mProgress)
        for (auto& integ : mIntegs)
            integ->decimator().setInterrupter([this, d = &integ->decimator()] {
                std::lock_guard<std::mutex> lock(mProgressMutex);
                return !mProgress->update(double(mDone) / double(mBlocks.size()), d->faceCount());
            });
    // A slab's first layer of leaves is also sampled by the slab below, but only its bottom voxel
    // plane: those leaves are freed like the others, keeping that plane until the slab below is done.
    std::vector<int32_t> seamZ;
    for (size_t si = 1; si < mSlabs.size(); ++si) seamZ.push_back(mSlabs[si].zStart);
    mVol->setSeams(seamZ);
    // Slabs run in parallel, as many at once as there are threads, and join slab 0's mesh in slab
    // order as each is done (and all below it have joined); the seam it closes is finalised and
    // decimated then, while the next slabs run. A slab waiting to join holds its seams open, so no
    // more slabs start than can run: open seams hold full-resolution faces and grow with the input.
    const size_t running = size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
    size_t nextSlab = 0;
    const double slabsStart = mClock.seconds();
    tbb::parallel_pipeline(
        running,
        indices(nextSlab, mSlabs.size()) &
            tbb::make_filter<size_t, size_t>(tbb::filter_mode::parallel,
                                             [&](size_t si) {
                                                 extractSlab(si);
                                                 // Dead entries are dropped before the queue is copied.
                                                 mIntegs[si]->decimator().compactQueue();
                                                 return si;
                                             }) &
            tbb::make_filter<size_t, void>(tbb::filter_mode::serial_in_order, [&](size_t si) {
                if (si > 0) mIntegs[0]->absorbSlab(*mIntegs[si], mSlabs[si].zStart);
            }));
    mResult.report.secondsSlabs = mClock.seconds() - slabsStart;
}

// One slab's blocks: extracted in parallel, integrated (and decimated every batch) in block order.
void PipelineRun::extractSlab(size_t si)
{
    const Slab& slab = mSlabs[si];
    Integrator& integ = *mIntegs[si];
    size_t next = slab.begin;
    const size_t tokens = 4 * std::max<size_t>(1, std::thread::hardware_concurrency());
    // Block meshes live in a ring of `tokens` slots rather than travelling as heap items: at most
    // `tokens` blocks are in flight and the last stage is in order, so block i + tokens never starts
    // before block i is integrated; and a cancelled pipeline leaves nothing behind (TBB does not
    // destroy items that are in flight when a stage throws).
    std::vector<BlockMesh> slots(tokens);
    tbb::parallel_pipeline(
        tokens,
        indices(next, slab.end) &
            tbb::make_filter<size_t, size_t>(tbb::filter_mode::parallel,
                                             [&](size_t i) {
                                                 meshBlock(si, i, slots[i % tokens]);
                                                 return i;
                                             }) &
            tbb::make_filter<size_t, void>(tbb::filter_mode::serial_in_order,
                                           [&](size_t i) { integrateBlock(integ, si, slots[i % tokens]); }));
    integ.finishSlab();
    if (si + 1 < mSlabs.size()) mVol->dropSeamPlanes(mSlabs[si + 1].zStart);
}

// Marching Cubes on block i of slab si. Thread-safe.
void PipelineRun::meshBlock(size_t si, size_t i, BlockMesh& m) const
{
    BlockSamples s;
    mVol->sample(mBlocks[i], s);
    m.blockIndex = i;
    const auto mm = std::minmax_element(s.values.begin(), s.values.end());
    m.minValue = *mm.first;
    m.maxValue = *mm.second;
    extractBlock(s, mCls, mInfo.indexToWorld, mFlip, m);
    if (mOpt.attributeWeight > 0) mAttributes->sampleFirst(m.positions, m.attribute);
    const int32_t seamZ = mSlabs[si].zStart;
    if (si > 0 && mBlocks[i][2] == seamZ)
        for (size_t v = 0; v < m.keys.size(); ++v) {
            const EdgeCoord e = decodeEdgeKey(m.keys[v]);
            if (e.z == seamZ && e.axis != 2) m.finalAfterBlock[v] = 0;  // on the seam: open until the slabs join
        }
}

// The in-order stage: the block's mesh joins its slab, its voxels are freed, progress is counted.
void PipelineRun::integrateBlock(Integrator& integ, size_t si, const BlockMesh& m)
{
    integ.add(m);
    const BlockOrigin& origin = mBlocks[m.blockIndex];
    if (si > 0 && origin[2] == mSlabs[si].zStart) mVol->releaseSeamLeaf(origin);
    else mVol->releaseLeaf(origin);
    std::lock_guard<std::mutex> lock(mProgressMutex);
    mSampled = {std::min(mSampled[0], m.minValue), std::max(mSampled[1], m.maxValue)};
    ++mDone;
    if (mDone % Volume::kTrimEveryBlocks == 0) mVol->trimInputMapping();
    // Released leaves are small heap objects: give the pages they emptied back.
    if (mDone % kMallocTrimEveryBlocks == 0) malloc_trim(0);
    if (mProgress && (mDone % kProgressEveryBlocks == 0 || mDone == mBlocks.size()) &&
        !mProgress->update(double(mDone) / double(mBlocks.size()), integ.decimator().faceCount()))
        throw Cancelled("cancelled");
}

// Every slab has joined slab 0: the final pass runs on the whole, and the report is completed.
Result PipelineRun::finalPass()
{
    Report& rep = mResult.report;
    const double finalStart = mClock.seconds();
    uint64_t facesGenerated = 0, intermediate = 0;
    for (const auto& integ : mIntegs) {
        facesGenerated += integ->facesGenerated();
        const SlabStats& st = integ->stats();
        rep.decimations += st.decimations;
        intermediate += st.maxIntermediateFaces;
        rep.maxUncontractibleFaces += st.maxUncontractibleFaces;
        rep.trace.insert(rep.trace.end(), st.trace.begin(), st.trace.end());
    }
    Integrator& whole = *mIntegs[0];
    rep.maxIntermediateFaces = std::max(intermediate, uint64_t(whole.decimator().faceCount()));

    if (mOpt.targetFaces == 0) rep.facesFull = facesGenerated;
    if (rep.facesFull == 0) throw noSurface();
    rep.ratio = mRatio;
    rep.facesTarget = mOpt.targetFaces > 0 ? std::min<uint64_t>(mOpt.targetFaces, rep.facesFull)
                                           : uint64_t(std::llround(mRatio * double(rep.facesFull)));
    uint64_t unfinalized = 0;
    const size_t seamVertices = whole.decimator().openVertices();
    const size_t traced = whole.stats().trace.size();
    whole.finish(rep.facesTarget, facesGenerated, unfinalized);
    rep.unfinalizedAtEnd = unfinalized - seamVertices;
    // Slabs absorbed into slab 0 keep what their own passes accepted.
    for (const auto& integ : mIntegs) rep.maxErrorAccepted = std::max(rep.maxErrorAccepted, integ->stats().maxErrorAccepted);
    rep.maxErrorAccepted = std::max(rep.maxErrorAccepted, whole.decimator().maxErrorAccepted());
    mAttributes->load();
    if (mOpt.lods.empty()) {
        mResult.mesh = whole.decimator().mesh();
        mResult.mesh.attributes = mAttributes->sample(mResult.mesh.points);
    } else {
        // Each level is made from the one before, handed over and let go; the last one is the result.
        mResult.mesh = makeLevels(whole, rep, mOpt, *mAttributes, mClock);
    }
    rep.trace.insert(rep.trace.end(), whole.stats().trace.begin() + traced, whole.stats().trace.end());
    rep.decimations += whole.stats().trace.size() - traced;
    rep.componentsDropped = whole.componentsDropped();
    rep.secondsFinal = mClock.seconds() - finalStart;
    rep.facesOut = mResult.mesh.triangles.size();
    rep.vertsOut = mResult.mesh.points.size();
    rep.seconds = mClock.seconds();
    rep.peakRssMb = peakRssMb();
    return std::move(mResult);
}

EmptySurfaceError PipelineRun::noSurface() const
{
    const auto range = mReleased ? mSampled : mVol->valueRange();
    std::ostringstream s;
    s << mPath << ": no surface at iso-value " << mCls.iso << " in grid '" << mInfo.gridName << "' (values lie in ["
      << range[0] << ", " << range[1] << "])";
    return EmptySurfaceError(s.str());
}

Result runPipeline(const VolumeOpener& open, const std::string& path, const Options& opt, Progress* progress)
{
    checkOptions(opt);
    PipelineRun run(path, opt, progress);
    run.openVolume(open);
    run.chooseIso();
    run.listBlocks();
    run.setTarget(open);
    run.runSlabs();
    return run.finalPass();
}

} // namespace

Result simplifyVolume(const VolumeOpener& open, const std::string& name, const Options& opt, Progress* progress)
{
    // Every input error names the input, whichever stage found it.
    try {
        // A thread count applies to this run only: an arena of its own, not a process-wide limit
        // that would hold every other TBB user of a host (Blender, Houdini, Python) while it runs.
        if (opt.threads <= 0) return runPipeline(open, name, opt, progress);
        tbb::task_arena arena(opt.threads);
        return arena.execute([&] { return runPipeline(open, name, opt, progress); });
    } catch (const InputError& e) {
        const std::string what = e.what();
        if (what.compare(0, name.size() + 1, name + ":") == 0) throw;
        throw InputError(name + ": " + what);
    }
}

Result simplifyFile(const std::string& path, const Options& opt, Progress* progress)
{
    return simplifyVolume([&] { return Volume::open(path, opt.gridName); }, path, opt, progress);
}

} // namespace vdb_isosimp
