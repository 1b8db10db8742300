// The driver: a script of named stages.
//   open (delayed loading) -> block list (z/y/x) -> [count faces, for --faces]
//   -> extract blocks (parallel) -> integrate in order + decimate every B faces -> final decimation.
#include "vdb_isosimp.h"

#include "block_order.h"
#include "decimator.h"
#include "edge_key.h"
#include "errors.h"
#include "input_checks.h"
#include "marching_cubes.h"
#include "pipeline_internal.h"
#include "run_stats.h"
#include "schedule.h"
#include "volume_reader.h"

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
    if (!(o.ratio > 0.0 && o.ratio <= 1.0)) {
        std::ostringstream s;
        s << "ratio must be in (0, 1], got " << o.ratio;
        throw InputError(s.str());
    }
    if (o.batchFaces < 1000) throw InputError("batch must be at least 1000 faces");
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

// A run of whole block layers (equal z), processed by its own integrator.
struct Slab {
    size_t begin = 0, end = 0;
    int32_t zStart = 0;
};

// Splits the z/y/x-sorted blocks into at most `count` slabs of about equal block counts, cutting only
// between block layers. The split depends on the volume alone, never on the thread count, so the
// output does not either.
std::vector<Slab> splitSlabs(const std::vector<BlockOrigin>& blocks, size_t count)
{
    std::vector<Slab> slabs;
    size_t begin = 0;
    for (size_t s = 0; s < count && begin < blocks.size(); ++s) {
        size_t end = s + 1 == count ? blocks.size() : std::max(begin + 1, blocks.size() * (s + 1) / count);
        while (end < blocks.size() && blocks[end][2] == blocks[end - 1][2]) ++end;
        slabs.push_back({begin, end, blocks[begin][2]});
        begin = end;
    }
    if (begin < blocks.size()) slabs.back().end = blocks.size();
    return slabs;
}

} // namespace

static Result runPipeline(const std::function<std::unique_ptr<Volume>()>& open, const std::string& path,
                          const Options& opt, Progress* progress)
{
    Stopwatch clock;
    checkOptions(opt);

    // Open.
    std::unique_ptr<Volume> vol = open();
    const VolumeInfo info = vol->info();  // a copy: the volume is opened again after counting
    // On this open, not one of its own: reading the topology of a large file takes a while (0.4 s at 448^3).
    if (opt.maxMemoryBytes > 0) checkMemoryBudget(path, info, opt, opt.maxMemoryBytes);
    Result result;
    Report& rep = result.report;
    rep.file = path;
    rep.grid = info.gridName;
    rep.valueType = info.valueType;
    rep.gridClass = info.levelSet ? "level set" : "fog";

    Classifier cls;
    cls.insideBelow = info.levelSet;
    if (opt.iso) {
        cls.iso = *opt.iso;
    } else if (info.levelSet) {
        cls.iso = 0.0;
    } else {
        const auto range = vol->valueRange();
        cls.iso = 0.5 * (range[0] + range[1]);
        rep.isoDefaulted = true;
    }
    rep.iso = cls.iso;
    // A mirroring transform reverses the winding; compensate so normals still point outward.
    const bool flip = info.indexToWorld.determinant() < 0;

    // Range of the values sampled so far; voxel buffers are released as blocks finish, so the grid
    // itself can no longer be asked once extraction has run.
    std::array<double, 2> sampled{info.background, info.background};
    bool released = false;
    auto noSurface = [&]() {
        const auto range = released ? sampled : vol->valueRange();
        std::ostringstream s;
        s << path << ": no surface at iso-value " << cls.iso << " in grid '" << info.gridName
          << "' (values lie in [" << range[0] << ", " << range[1] << "])";
        return EmptySurfaceError(s.str());
    };

    // Block list.
    const std::vector<BlockOrigin> blocks = vol->blocks(cls);
    rep.blocks = blocks.size();

    // Targets.
    double ratio = opt.ratio;
    if (opt.targetFaces > 0) {
        // Counted on the volume itself, which frees leaves as it goes, then opened again for
        // extraction: one copy of the topology at a time. (Counting on a second copy made the start
        // of a run its peak on large inputs kept to small outputs: 17 MB of topology twice at 448^3.)
        rep.facesFull = countFaces(*vol, blocks, cls);
        vol.reset();
        malloc_trim(0);
        vol = open();
        if (rep.facesFull == 0) throw noSurface();
        ratio = std::min(1.0, double(opt.targetFaces) / double(rep.facesFull));
    }

    // Slabs: whole block layers, each extracted and decimated on its own, in parallel when threads
    // allow. Vertices on the x/y edges of a slab's first voxel layer are shared with the slab below,
    // so they stay open there (a seam) until the slabs are merged; every other vertex follows the
    // modifiability rule inside its slab. Each slab gets B/S faces per batch, so the intermediate
    // meshes together stay within R*F + B plus the uncontractible faces.
    const std::vector<Slab> slabs = splitSlabs(blocks, kPipelineSlabs);
    const uint64_t batch = std::max<uint64_t>(1000, opt.batchFaces / slabs.size());
    std::vector<std::unique_ptr<Integrator>> integs;
    for (uint32_t i = 0; i < slabs.size(); ++i) integs.push_back(std::make_unique<Integrator>(opt, ratio, batch, i));
    // The decimator's least face weight is a fraction of a voxel face, in world units.
    const double voxelArea = std::pow(std::abs(info.indexToWorld.determinant()), 2.0 / 3.0);
    for (auto& integ : integs) integ->decimator().setVoxelArea(voxelArea);
    released = true;
    std::mutex progressMutex;
    size_t done = 0;
    // Decimation passes poll the same progress object, so a cancel request stops them too.
    if (progress)
        for (auto& integ : integs)
            integ->decimator().setInterrupter([&, d = &integ->decimator()] {
                std::lock_guard<std::mutex> lock(progressMutex);
                return !progress->update(double(done) / double(blocks.size()), d->faceCount());
            });
    // A slab's first layer of leaves is also sampled by the slab below, but only its bottom voxel
    // plane: those leaves are freed like the others, keeping that plane until the slab below is done.
    // (Holding the whole layer instead kept a layer of voxels per seam loaded: 6 MB a seam at 448^3.)
    std::vector<int32_t> seamZ;
    for (size_t si = 1; si < slabs.size(); ++si) seamZ.push_back(slabs[si].zStart);
    vol->setSeams(seamZ);
    auto runSlab = [&](size_t si) {
        const Slab& slab = slabs[si];
        Integrator& integ = *integs[si];
        const bool seam = si > 0;
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
                tbb::make_filter<size_t, size_t>(
                    tbb::filter_mode::parallel,
                    [&](size_t i) {
                        BlockSamples s;
                        vol->sample(blocks[i], s);
                        BlockMesh* m = &slots[i % tokens];
                        m->blockIndex = i;
                        const auto mm = std::minmax_element(s.values.begin(), s.values.end());
                        m->minValue = *mm.first;
                        m->maxValue = *mm.second;
                        extractBlock(s, cls, info.indexToWorld, flip, *m);
                        if (seam && blocks[i][2] == slab.zStart)
                            for (size_t v = 0; v < m->keys.size(); ++v) {
                                const EdgeCoord e = decodeEdgeKey(m->keys[v]);
                                if (e.z == slab.zStart && e.axis != 2) m->finalAfterBlock[v] = 0;
                            }
                        return i;
                    }) &
                tbb::make_filter<size_t, void>(
                    tbb::filter_mode::serial_in_order, [&](size_t i) {
                        const BlockMesh* m = &slots[i % tokens];
                        integ.add(*m);
                        if (seam && blocks[m->blockIndex][2] == slab.zStart) vol->releaseSeamLeaf(blocks[m->blockIndex]);
                        else vol->releaseLeaf(blocks[m->blockIndex]);
                        std::lock_guard<std::mutex> lock(progressMutex);
                        sampled = {std::min(sampled[0], m->minValue), std::max(sampled[1], m->maxValue)};
                        ++done;
                        if (done % Volume::kTrimEveryBlocks == 0) vol->trimInputMapping();
                        // Released leaves are small heap objects: give the pages they emptied back.
                        if (done % 4096 == 0) malloc_trim(0);
                        if (progress && (done % 256 == 0 || done == blocks.size()) &&
                            !progress->update(double(done) / double(blocks.size()), integ.decimator().faceCount()))
                            throw Cancelled("cancelled");
                    }));
        integ.finishSlab();
        if (si + 1 < slabs.size()) vol->dropSeamPlanes(slabs[si + 1].zStart);
    };
    // Slabs run in parallel, as many at once as there are threads, and join slab 0's mesh in slab
    // order as each is done (and all below it have joined); the seam it closes is finalised and
    // decimated then, while the next slabs run. A slab waiting to join holds its seams open, so no
    // more slabs start than can run: open seams hold full-resolution faces and grow with the input.
    const size_t running = size_t(std::max(1, tbb::this_task_arena::max_concurrency()));
    size_t nextSlab = 0;
    const double slabsStart = clock.seconds();
    tbb::parallel_pipeline(
        running,
        indices(nextSlab, slabs.size()) &
            tbb::make_filter<size_t, size_t>(tbb::filter_mode::parallel,
                                             [&](size_t si) {
                                                 runSlab(si);
                                                 // Dead entries are dropped before the queue is copied.
                                                 integs[si]->decimator().compactQueue();
                                                 return si;
                                             }) &
            tbb::make_filter<size_t, void>(tbb::filter_mode::serial_in_order, [&](size_t si) {
                if (si > 0) integs[0]->absorbSlab(*integs[si], slabs[si].zStart);
            }));
    rep.secondsSlabs = clock.seconds() - slabsStart;
    const double finalStart = clock.seconds();

    // Every slab has joined slab 0: the final pass runs on the whole.
    uint64_t facesGenerated = 0, intermediate = 0;
    for (const auto& integ : integs) {
        facesGenerated += integ->facesGenerated();
        const SlabStats& st = integ->stats();
        rep.decimations += st.decimations;
        intermediate += st.maxIntermediateFaces;
        rep.maxUncontractibleFaces += st.maxUncontractibleFaces;
        rep.trace.insert(rep.trace.end(), st.trace.begin(), st.trace.end());
    }
    Integrator& whole = *integs[0];
    rep.maxIntermediateFaces = std::max(intermediate, uint64_t(whole.decimator().faceCount()));

    if (opt.targetFaces == 0) rep.facesFull = facesGenerated;
    if (rep.facesFull == 0) throw noSurface();
    rep.ratio = ratio;
    rep.facesTarget = opt.targetFaces > 0 ? std::min<uint64_t>(opt.targetFaces, rep.facesFull)
                                          : uint64_t(std::llround(ratio * double(rep.facesFull)));
    uint64_t unfinalized = 0;
    const size_t seamVertices = whole.decimator().openVertices();
    const size_t traced = whole.stats().trace.size();
    whole.finish(rep.facesTarget, facesGenerated, unfinalized);
    rep.unfinalizedAtEnd = unfinalized - seamVertices;
    rep.trace.insert(rep.trace.end(), whole.stats().trace.begin() + traced, whole.stats().trace.end());
    rep.decimations += whole.stats().trace.size() - traced;
    rep.componentsDropped = whole.componentsDropped();
    rep.secondsFinal = clock.seconds() - finalStart;
    result.mesh = whole.decimator().mesh();
    rep.facesOut = result.mesh.triangles.size();
    rep.vertsOut = result.mesh.points.size();
    rep.seconds = clock.seconds();
    rep.peakRssMb = peakRssMb();
    return result;

}

Result simplifyVolume(const std::function<std::unique_ptr<Volume>()>& open, const std::string& name,
                      const Options& opt, Progress* progress)
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
