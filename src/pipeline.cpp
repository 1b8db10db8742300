// The driver: a script of named stages.
//   open (delayed loading) -> block list (z/y/x) -> [count faces, for --faces]
//   -> extract blocks (parallel) -> integrate in order + decimate every B faces -> final decimation.
#include "vdb_isosimp.h"

#include "block_order.h"
#include "decimator.h"
#include "errors.h"
#include "marching_cubes.h"
#include "run_stats.h"
#include "volume_reader.h"

#include <tbb/global_control.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_reduce.h>
#include <tbb/blocked_range.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <sstream>
#include <thread>

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

// Exact face count of the full-resolution surface: the same case table over the same blocks.
uint64_t countFaces(const Volume& vol, const std::vector<BlockOrigin>& blocks, const Classifier& cls)
{
    return tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, blocks.size(), 16), uint64_t(0),
        [&](const tbb::blocked_range<size_t>& r, uint64_t n) {
            BlockSamples s;
            for (size_t i = r.begin(); i != r.end(); ++i) {
                vol.sample(blocks[i], s);
                n += countBlockTriangles(s, cls);
            }
            return n;
        },
        [](uint64_t a, uint64_t b) { return a + b; });
}

// Serial, in-order stage: integration and the decimation schedule of the paper's section 4.2.
class Integrator {
public:
    Integrator(const Options& o, double ratio, Report& rep) : mOpt(o), mRatio(ratio), mRep(rep)
    {
        mInitial = ratio < o.initialRatio;
    }

    void add(const BlockMesh& b)
    {
        const uint64_t incoming = b.triangles.size();
        if (incoming == 0 && b.keys.empty()) return;
        if (mInitial) {
            // Initial phase: let the intermediate mesh grow to B faces, then decimate it at rate R_i,
            // until the regular target catches up (avoids over-decimating the first batches). Never
            // below the regular target: the final mesh must still be able to reach R*F.
            if (mDec.faceCount() + incoming > mOpt.batchFaces && mDec.faceCount() > 0) {
                const uint64_t initial = phaseTarget(double(mDec.faceCount()), mOpt.initialRatio);
                const uint64_t regular = phaseTarget(double(mFacesGenerated), mRatio);
                if (regular >= initial) mInitial = false;
                decimate(std::max(initial, regular));
                mSinceLast = 0;
            }
        } else if (mSinceLast + incoming > mOpt.batchFaces && mSinceLast > 0) {
            decimate(phaseTarget(double(mFacesGenerated), mRatio));
            mSinceLast = 0;
        }
        mDec.addBlock(b);
        mFacesGenerated += incoming;
        mSinceLast += incoming;
        mRep.maxIntermediateFaces = std::max<uint64_t>(mRep.maxIntermediateFaces, mDec.faceCount());
    }

    void finish(uint64_t targetFaces)
    {
        mRep.unfinalizedAtEnd = mDec.finalizeRemaining();
        decimate(targetFaces);
        // Collapses refused earlier (link condition, fold-overs) may be legal now: retry until stuck.
        // Then, only if still above target, allow larger normal turns step by step (never a flip).
        for (double turn : {0.17, 0.0, -0.3, -0.6}) {
            mDec.setMaxNormalTurn(turn);
            while (mDec.faceCount() > targetFaces) {
                mDec.requeueAll();
                if (mDec.decimateTo(targetFaces) == 0) break;
            }
        }
        mDec.setMaxNormalTurn(0.17);
        // Below R = 1, no zero-area face may survive (R = 1 is the exact Marching Cubes surface).
        if (targetFaces < mFacesGenerated) mDec.removeDegenerateFaces();
    }

    uint64_t facesGenerated() const { return mFacesGenerated; }
    const Decimator& decimator() const { return mDec; }

private:
    // F_t = (F - F_u) * rate + F_u: only the contractible part of the mesh is held to the rate.
    uint64_t phaseTarget(double faces, double rate) const
    {
        const double fu = double(mDec.uncontractibleFaces());
        return uint64_t(std::max(0.0, faces - fu) * rate + fu);
    }

    void decimate(uint64_t target)
    {
        DecimationRecord rec{mFacesGenerated, mDec.faceCount(), 0, mDec.uncontractibleFaces(), target};
        mRep.maxUncontractibleFaces = std::max<uint64_t>(mRep.maxUncontractibleFaces, rec.uncontractible);
        mDec.decimateTo(target);
        rec.facesAfter = mDec.faceCount();
        mRep.trace.push_back(rec);
        ++mRep.decimations;
    }

    const Options& mOpt;
    double mRatio;
    Report& mRep;
    Decimator mDec;
    bool mInitial = false;
    uint64_t mFacesGenerated = 0, mSinceLast = 0;
};

} // namespace

static Result simplifyFileUnprefixed(const std::string& path, const Options& opt, Progress* progress)
{
    Stopwatch clock;
    checkOptions(opt);
    std::unique_ptr<tbb::global_control> threads;
    if (opt.threads > 0)
        threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, opt.threads);

    // Open.
    std::unique_ptr<Volume> vol = Volume::open(path, opt.gridName);
    const VolumeInfo& info = vol->info();
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
        rep.facesFull = countFaces(*vol, blocks, cls);
        if (rep.facesFull == 0) throw noSurface();
        ratio = std::min(1.0, double(opt.targetFaces) / double(rep.facesFull));
    }

    {
        // Extract in parallel, integrate and decimate in order. The number of blocks in flight is
        // bounded, so memory is too; the in-order stage makes the output independent of threads.
        Integrator integ(opt, ratio, rep);
        released = true;
        size_t next = 0, done = 0;
        const size_t tokens = 4 * std::max<size_t>(1, std::thread::hardware_concurrency());
        tbb::parallel_pipeline(
            tokens,
            tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order,
                                           [&](tbb::flow_control& fc) -> size_t {
                                               if (next == blocks.size()) { fc.stop(); return 0; }
                                               return next++;
                                           }) &
                tbb::make_filter<size_t, std::shared_ptr<BlockMesh>>(
                    tbb::filter_mode::parallel,
                    [&](size_t i) {
                        BlockSamples s;
                        vol->sample(blocks[i], s);
                        auto m = std::make_shared<BlockMesh>();
                        m->blockIndex = i;
                        const auto mm = std::minmax_element(s.values.begin(), s.values.end());
                        m->minValue = *mm.first;
                        m->maxValue = *mm.second;
                        extractBlock(s, cls, info.indexToWorld, flip, *m);
                        return m;
                    }) &
                tbb::make_filter<std::shared_ptr<BlockMesh>, void>(
                    tbb::filter_mode::serial_in_order, [&](std::shared_ptr<BlockMesh> m) {
                        sampled = {std::min(sampled[0], m->minValue), std::max(sampled[1], m->maxValue)};
                        integ.add(*m);
                        vol->releaseLeaf(blocks[m->blockIndex]);
                        ++done;
                        if (progress && (done % 256 == 0 || done == blocks.size()) &&
                            !progress->update(double(done) / double(blocks.size()), integ.decimator().faceCount()))
                            throw Cancelled("cancelled");
                    }));

        if (opt.targetFaces == 0) rep.facesFull = integ.facesGenerated();
        if (rep.facesFull == 0) throw noSurface();
        rep.ratio = ratio;
        rep.facesTarget = opt.targetFaces > 0 ? std::min<uint64_t>(opt.targetFaces, rep.facesFull)
                                              : uint64_t(std::llround(ratio * double(rep.facesFull)));
        integ.finish(rep.facesTarget);
        result.mesh = integ.decimator().mesh();
    }
    rep.facesOut = result.mesh.triangles.size();
    rep.vertsOut = result.mesh.points.size();
    rep.seconds = clock.seconds();
    rep.peakRssMb = peakRssMb();
    return result;

}

Result simplifyFile(const std::string& path, const Options& opt, Progress* progress)
{
    // Every input error names the file, whichever stage found it.
    try {
        return simplifyFileUnprefixed(path, opt, progress);
    } catch (const InputError& e) {
        const std::string what = e.what();
        if (what.compare(0, path.size() + 1, path + ":") == 0) throw;
        throw InputError(path + ": " + what);
    }
}

} // namespace vdb_isosimp
