// The driver: a script of named stages (runPipeline).
//   open (delayed loading) -> iso-value -> block list (z/y/x) -> slabs -> the leaves of this
//   process's slabs, laid out in sweep order -> [count faces, for a face target]
//   -> slabs: extract blocks (parallel), integrate in order + decimate every B faces
//   -> merge tree: siblings join, their seam is finalised and decimated (subtrees in parallel; with
//      MPI ranks, each rank's subtree travels to its parent's rank) -> final decimation.
#include "vdb_isosimp/vdb_isosimp.h"

#include "core/decimator.h"
#include "core/edge_key.h"
#include "core/marching_cubes.h"
#include "core/piece_bytes.h"
#include "core/schedule.h"
#include "pipeline/face_count.h"
#include "pipeline/levels.h"
#include "pipeline/memory_budget.h"
#include "pipeline/pipeline_internal.h"
#include "pipeline/run_stats.h"
#include "pipeline/slabs.h"
#include "vdb/attribute_sampler.h"
#include "vdb/block_order.h"
#include "vdb/volume_reader.h"
#include "vdb_isosimp/errors.h"

#include <tbb/info.h>
#include <tbb/task_arena.h>
#include <tbb/task_group.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/parallel_for.h>
#include <tbb/blocked_range.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <exception>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>
#include <tuple>

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
    if (o.blocksPerSlab < 1) throw InputError("blocks per slab must be at least 1");
    if (!(o.minComponentArea >= 0.0 && std::isfinite(o.minComponentArea)))
        throw InputError("minimum component area must be a finite number >= 0");
}

// One run of the pipeline over one volume: the stages in the order runPipeline calls them, and the
// state they hand on.
class PipelineRun {
public:
    PipelineRun(const std::string& path, const Options& opt, Progress* progress, RankChannel* ranks)
        : mPath(path), mOpt(opt), mProgress(progress), mRanks(ranks)
    {
    }

    void openVolume(const VolumeOpener& open);
    void chooseIso();
    std::array<double, 2> valueRange() const;
    // Every rank meets the others' agreement on the value range once (chooseIso), a rank that failed
    // before it too (failBeforeRange): the others would wait in it otherwise.
    std::array<double, 2> agreeOnRange(std::array<double, 2> range, bool failed) const;
    void failBeforeRange() const;
    mutable bool mRangeAgreed = false, mRangeFailed = false;
    void listBlocks();
    void gatherBlocks(bool failed);
    // A rank that fails after the value range and before the block list meets the others' exchange
    // of the list (gatherBlocks) once, failed: they would wait in it otherwise.
    void failBeforeBlocks();
    bool mBlocksGathered = false;
    void splitSlabs();
    void keepOwnLeaves();
    void countFacesForTarget();
    bool sampleTooCoarse() const;
    void countFacesExactly();
    void countFacesOver(uint64_t sampleRuns);
    void agreeAmongRanks(const std::string& error);
    // The end of a rank's set-up (its share of the topology read, its blocks listed and merged, the cut,
    // its leaves laid out): the process's CPU seconds since the run began, less those spent in the
    // ranks' collectives (RankChannel::collectiveCpuSeconds), for the scaling model (docs/scale.md).
    void setupDone();
    double mSetupCpu = 0.0;
    const double mStartCpu = processCpuSeconds();
    void setTarget();
    bool runTree();
    Result finalPass();
    Result rankReport();

private:
    Levels rankSubtree(size_t l, size_t r, size_t a, size_t b);
    Levels localSubtree(size_t l, size_t r);
    void join(Levels& left, std::vector<SlabPiece>&& right, size_t l, size_t r) const;
    // The right side: a piece from another rank, or the sibling itself in this process.
    template <typename Right>
    void joinLevel(Integrator& left, Right&& right, size_t l, size_t r) const;
    bool wholeTree(size_t l, size_t r) const { return l == 0 && r == mSlabs.size(); }
    Levels extractSlab(size_t si);
    void watch(Decimator& dec);
    void countLeafSamplers(size_t begin, size_t end);
    void meshBlock(size_t si, size_t i, BlockMesh& m) const;
    void integrateBlock(Integrator& integ, const BlockMesh& m);
    void releaseSampledLeaves(size_t i);
    size_t lowerBoundFrom(const BlockOrigin& o, size_t from) const;
    // The blocks in z/y/x order with their index in mBlocks, and each block's place here: the leaves a
    // block samples lie +x, +y and +z of it, the next block, a row or a layer on in this order, where the
    // tree's order may put them a subtree away (and compares by walking its cuts). The places come with
    // the cut (arrangeBlocks), the list with the leaf counts; both go with the leaf counts. Tens of
    // megabytes on a large volume, written at once: pooled, they take huge pages (a page fault per 2 MiB).
    PooledVector<std::pair<BlockOrigin, uint32_t>> mSweep;
    PooledVector<uint32_t> mSweepAt;
    template <typename F>
    void forSampledLeaves(size_t i, F&& f) const;
    std::pair<size_t, size_t> rankBlocks() const;
    std::pair<size_t, size_t> rankSlabRange() const;  // the slabs this process extracts
    std::vector<char> rankMessage(std::vector<SlabPiece>&& levels) const;
    std::vector<SlabPiece> readRankMessage(const std::vector<char>& bytes);
    EmptySurfaceError noSurface() const;

    static constexpr size_t kMallocTrimEveryBlocks = 4096;
    static constexpr uint8_t kEarlySampler = 16;  // one early reader in mLeafSamplers (up to 8 readers each)

    const std::string& mPath;
    const Options& mOpt;
    Progress* mProgress;
    RankChannel* mRanks;  // null: this process runs the whole tree
    Stopwatch mClock;
    Result mResult;
    std::unique_ptr<Volume> mVol;
    std::unique_ptr<AttributeSampler> mAttributes;  // Options::attributes, checked at open
    VolumeInfo mInfo;
    Classifier mCls;
    bool mFlip = false;
    std::vector<BlockOrigin> mBlocks;
    double mRatio = 0.0;
    CountRuns mCountRuns;  // a face target's count: the runs of blocks it reads
    FaceCount mCount;      // and what they hold, summed over the ranks by agreeAmongRanks
    BlockOrder mOrder;
    std::vector<Slab> mSlabs;
    uint64_t mSlabBatch = 0;
    double mVoxelArea = 0.0;
    Levels mRoot;  // the tree's result: the whole surface, per level (rank 0 only, in a distributed run)
    // How many blocks still to be integrated sample each block's leaf (its own block and the up to 7
    // below, behind and left of it that this process extracts): at zero the leaf is freed. In the high
    // four bits, how many of them lie more than a slab before the leaf's own (the layer below a cut of
    // the merge tree, a subtree ahead of it): when those are done the leaf is parked until its own slabs
    // read it again, unless they have started. Per block, which of its leaves it reads that early.
    std::unique_ptr<std::atomic<uint8_t>[]> mLeafSamplers;
    std::unique_ptr<uint8_t[]> mEarlyReads;
    std::mutex mParkMutex;  // slab starts against parking: a started slab may be reading a leaf
    size_t mSlabsStarted = 0;  // slabs of this process below this index have started
    size_t slabOf(size_t block) const;
    void parkOrKeep(size_t leaf, const BlockOrigin& origin);
    size_t mRankBlocks = 0;  // blocks this process extracts (all of them without ranks)
    // Seconds, peak memory (MB), bytes sent and set-up CPU seconds (setupDone) of each rank below this
    // one, gathered up the tree with the meshes; and the seconds of each node made here.
    std::vector<std::array<double, 4>> mRanksBelow;
    std::mutex mTreeMutex;
    std::vector<Report::TreeNode> mTree;
    void timed(size_t l, size_t r, double start);
    // Range of the values sampled so far; voxel buffers are released as blocks finish, so the grid
    // itself can no longer be asked once extraction has run.
    std::array<double, 2> mSampled{0.0, 0.0};
    bool mReleased = false;
    std::mutex mProgressMutex;  // guards mSampled, mDone and the progress object
    size_t mDone = 0;
    // Blocks per slab batch: B is shared by up to this many slabs in progress at once, so their
    // intermediate meshes together stay within R*F + B on up to 8 cores.
    static constexpr uint64_t kBatchShares = 8;
};

void PipelineRun::openVolume(const VolumeOpener& open)
{
    const double start = mClock.seconds();
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
    rep.secondsOpen = mClock.seconds() - start;
    rep.secondsCheck = mInfo.checkSeconds;
    rep.secondsTopology = mInfo.topologySeconds;
}

void PipelineRun::chooseIso()
{
    const double start = mClock.seconds();
    mCls.insideBelow = mInfo.levelSet;
    if (mOpt.iso || mInfo.levelSet) {
        mCls.iso = mOpt.iso ? *mOpt.iso : 0.0;
        if (mRanks) agreeOnRange({0.0, 0.0}, false);  // the ranks' collective, met by every rank
    } else {
        const auto range = valueRange();
        mCls.iso = 0.5 * (range[0] + range[1]);
        mResult.report.isoDefaulted = true;
    }
    mResult.report.iso = mCls.iso;
    mResult.report.secondsBlocks = mClock.seconds() - start;
}

// The grid's value range. With ranks, each reads its part of the leaves and the ranks agree on the
// smallest and largest (the same range, so the same iso-value, as one process reading them all).
std::array<double, 2> PipelineRun::valueRange() const
{
    if (!mRanks) return mVol->valueRange();
    std::array<double, 2> range{HUGE_VAL, -HUGE_VAL};
    std::exception_ptr failed;
    try {
        range = mVol->valueRange(mRanks->rank(), mRanks->ranks());
    } catch (...) {
        failed = std::current_exception();
    }
    range = agreeOnRange(range, failed != nullptr);
    if (failed) std::rethrow_exception(failed);
    return range;
}

std::array<double, 2> PipelineRun::agreeOnRange(std::array<double, 2> range, bool failed) const
{
    mRangeAgreed = true;
    mRangeFailed = true;  // until every rank is known to have its range
    range = mRanks->agreeRange(range, failed);
    mRangeFailed = failed;
    return range;
}

void PipelineRun::failBeforeRange() const
{
    if (mRanks && !mRangeAgreed) agreeOnRange({0.0, 0.0}, true);
}

void PipelineRun::listBlocks()
{
    const double start = mClock.seconds();
    // Blocks along tile faces are known once the iso-value is: a few large tiles can describe a
    // surface far larger than their leaves suggest, so the budget is checked again before listing them.
    if (mOpt.maxMemoryBytes > 0)
        if (const uint64_t shells = mVol->tileShellBlocks(mCls))
            checkMemoryBudget(mPath, mInfo, mOpt, mOpt.maxMemoryBytes, shells);
    if (mRanks && mRanks->ranks() > 1) {
        // Each rank lists its share of the leaves' and tiles' blocks; the ranks exchange them and each
        // merges the parts into the whole list, the one a single process lists.
        mBlocks = mVol->blocks(mCls, mRanks->rank(), mRanks->ranks());
        gatherBlocks(false);
    } else {
        mBlocks = mVol->blocks(mCls);
    }
    mResult.report.blocks = mBlocks.size();
    mResult.report.secondsBlocks += mClock.seconds() - start;
    if (mBlocks.empty()) throw noSurface();
}

void PipelineRun::gatherBlocks(bool failed)
{
    const double start = mClock.seconds();
    mBlocksGathered = true;
    std::vector<size_t> runEnds;
    mRanks->gatherBlocks(mBlocks, runEnds, failed);
    if (failed) return;
    mergeBlockRuns(mBlocks, runEnds);
    mResult.report.secondsBlocksMerge = mClock.seconds() - start;
    mResult.report.blockMergeRounds = uint64_t(std::ceil(std::log2(double(runEnds.size()))));
}

void PipelineRun::failBeforeBlocks()
{
    if (mRanks && mRanks->ranks() > 1 && mRangeAgreed && !mRangeFailed && !mBlocksGathered) gatherBlocks(true);
}

// For a face target: the faces of the full-resolution surface, counted over this process's blocks
// (with ranks, each counts its own share and agreeAmongRanks adds them up); on a large volume over a
// sample of them (Options::countSampleRuns).
void PipelineRun::countFacesForTarget()
{
    if (mOpt.targetFaces > 0) countFacesOver(mOpt.countSampleRuns);
}

// The sample counted too few faces to say how many there are: every block is counted instead.
bool PipelineRun::sampleTooCoarse() const
{
    return mOpt.targetFaces > 0 && mCountRuns.stride > 1 && estimateMargin(mCountRuns, mCount) > kCountMarginMost;
}

void PipelineRun::countFacesExactly()
{
    countFacesOver(0);
}

void PipelineRun::countFacesOver(uint64_t sampleRuns)
{
    const auto [begin, end] = rankBlocks();
    const double start = mClock.seconds();
    mCountRuns = countRuns(mSlabs, sampleRuns);
    mResult.report.countStride = mCountRuns.stride;
    mCount = countFaces(*mVol, mBlocks, mCountRuns, begin, end, mCls, [this](double fraction) {
        return !mProgress || mProgress->counting(fraction);
    });
    // The count and the trim of what it freed (each rank its own share): they divide among ranks.
    malloc_trim(0);
    mResult.report.secondsCount += mClock.seconds() - start;
}

void PipelineRun::setTarget()
{
    // A LOD chain is extracted at its finest rate; the final pass makes the coarser levels from it.
    mRatio = mOpt.lods.empty() ? mOpt.ratio : mOpt.lods.front();
    if (mOpt.targetFaces == 0) return;
    if (mCountRuns.stride == 1) {
        if (mCount.faces == 0) throw noSurface();
        mResult.report.facesFull = mCount.faces;
        mRatio = std::min(1.0, double(mOpt.targetFaces) / double(mCount.faces));
        return;
    }
    // A sampled count: the sampled faces scaled to all blocks, taken the margin low. The report's
    // full count is the exact one extraction makes.
    const double estimate = estimatedFaces(mCountRuns, mBlocks.size(), mCount);
    const double margin = estimateMargin(mCountRuns, mCount);
    mRatio = std::min(1.0, double(mOpt.targetFaces) / (estimate * (1.0 - margin)));
    mResult.report.countMargin = margin;
}

// Slabs: runs of consecutive blocks, each extracted and decimated on its own by its own integrator.
// A vertex whose edge is shared with blocks of another slab stays open there (a seam) until the merge
// tree joins the two; every other vertex follows the modifiability rule inside its slab.
void PipelineRun::splitSlabs()
{
    const double start = mClock.seconds();
    const size_t slabs = std::min(slabCount(mBlocks.size(), mOpt.blocksPerSlab), mBlocks.size());
    mSlabs = vdb_isosimp::splitSlabs(mBlocks, slabs);
    // A rank arranges its own slabs and cuts the nodes above them: the rest of the order is other ranks'.
    const auto [first, end] = rankSlabRange();
    mOrder = arrangeBlocks(mBlocks, slabs, &mSweepAt, first, end);
    mResult.report.slabs = mSlabs.size();
    mSlabBatch = std::max<uint64_t>(1000, mOpt.batchFaces / kBatchShares);
    // The decimator's least face weight is a fraction of a voxel face, in world units.
    mVoxelArea = std::pow(std::abs(mInfo.indexToWorld.determinant()), 2.0 / 3.0);
    mResult.report.secondsCut = mClock.seconds() - start;
}

// The leaves this process's blocks sample, laid out in sweep order; with ranks, the others go. A
// leaf is sampled by its own block and the up to 7 below it (sampledLeaf): it stays if one of those
// falls within this process's run of the block order (a position there that is no block keeps a leaf
// that nobody reads, which is harmless), a test per leaf instead of a set of every sampled leaf.
void PipelineRun::keepOwnLeaves()
{
    const double start = mClock.seconds();
    const auto [begin, end] = rankBlocks();
    // A rank opened its share of the topology: what its own blocks sample comes in now (all of it for a
    // rank that holds every block).
    if (mRanks && begin < end) mVol->readAround(mBlocks.data() + begin, end - begin);
    std::function<bool(const BlockOrigin&)> keep;  // empty: every leaf (one process)
    if (begin != 0 || end != mBlocks.size()) {
        const auto within = [&, slabs = rankSlabRange()](const BlockOrigin& b) {
            return slabs.first < slabs.second && mOrder.slabSide(b, slabs.first, slabs.second) == 0;
        };
        keep = [within](const BlockOrigin& leaf) {
            for (int d = 0; d < 8; ++d)
                if (within(samplingBlock(leaf, d))) return true;
            return false;
        };
    }
    mVol->keepLeaves(keep);
    // Each rank reads and lays out its own share: the scaling model divides it among workers.
    mResult.report.secondsLayout = mClock.seconds() - start;
}

void PipelineRun::setupDone()
{
    if (mRanks) mSetupCpu = processCpuSeconds() - mStartCpu - mRanks->collectiveCpuSeconds();
}

// Ranks agree that each has the same block list before the tree: a rank that could not start
// (unreadable file there) stops all of them, with its message on rank 0.
void PipelineRun::agreeAmongRanks(const std::string& error)
{
    if (!mRanks) return;
    const std::array<uint64_t, 2> sums = mRanks->agree(error, mBlocks.size(), {mCount.faces, mCount.squares});
    mCount = {sums[0], sums[1]};
}

// The merge tree (slabs.h): this process's node of it, made from its slabs and the nodes its child
// ranks send, then handed to its parent's rank. Returns true where the whole surface is (rank 0).
bool PipelineRun::runTree()
{
    const size_t rank = mRanks ? mRanks->rank() : 0, ranks = mRanks ? mRanks->ranks() : 1;
    const RankNode node = rankNode(mSlabs.size(), rank, ranks);
    mReleased = true;
    if (!node.found) {  // more ranks than slabs: nothing to do here
        mResult.report.secondsSlabs = 0.0;
        return false;
    }
    const auto [begin, end] = rankBlocks();
    countLeafSamplers(begin, end);
    const double start = mClock.seconds();
    Levels result;
    try {
        result = rankSubtree(node.l, node.r, node.a, node.b);
    } catch (const std::exception& e) {
        if (rank > 0) mRanks->send(node.parent, {}, e.what());
        throw;
    }
    mResult.report.secondsSlabs = mClock.seconds() - start;
    if (rank == 0) {
        mRoot = std::move(result);
        return true;
    }
    mRanks->send(node.parent, rankMessage(takePieces(result)), {});
    return false;
}

// Node [l, r) of the tree with ranks [a, b) sharing it (this process is rank a): the left child is
// made here, the right one by the first rank of its share, received when the left one is done.
Levels PipelineRun::rankSubtree(size_t l, size_t r, size_t a, size_t b)
{
    if (b - a < 2 || r - l < 2) return localSubtree(l, r);
    const size_t m = mergeSplit(l, r);
    const RankShare share = splitRanks(l, r, a, b);
    Levels left;
    try {
        left = rankSubtree(l, m, a, share.leftEnd);
        const double start = mClock.seconds();
        for (auto& level : left) level->park();  // while the right child's rank works
        timed(l, m, start);
    } catch (...) {
        // The right child's rank waits until its node is taken: take it (or its error) before leaving.
        try {
            mRanks->receive(share.rightBegin);
        } catch (const std::exception&) {
        }
        throw;
    }
    std::vector<SlabPiece> right = readRankMessage(mRanks->receive(share.rightBegin));
    const double start = mClock.seconds();
    join(left, std::move(right), l, r);
    timed(l, r, start);
    return left;
}

// Node [l, r) in this process, walked in slab order: as many slabs at once as threads, and each node
// joined at once by the thread that finishes its second child. Finished nodes waiting for a sibling
// form one frontier (a post-order walk); splitting the threads between the two halves of every node
// kept two frontiers open, each node on them holding its seams at full resolution. The tree's shape,
// hence the mesh, is slabs.h's either way. A LOD chain's levels are independent meshes, so each level
// climbs the tree on its own: a thread done with a coarse level's join takes that level on up instead
// of waiting at every node for the finest level, whose joins are the largest. Where this subtree is the
// whole tree, a coarser level's final pass follows its last join at once, while the finest level's top
// joins still run (a chain without a face target: the full surface's faces are the root's).
Levels PipelineRun::localSubtree(size_t l, size_t r)
{
    std::mutex waitingMutex;
    // Finished nodes of one level whose sibling (of the same level) is not: (first, end slab, level).
    std::map<std::tuple<size_t, size_t, size_t>, std::unique_ptr<Integrator>> waiting;
    Levels whole(std::max<size_t>(1, mOpt.lods.size()));
    size_t next = l;
    tbb::parallel_pipeline(
        std::max(1, tbb::this_task_arena::max_concurrency()),
        indices(next, r) & tbb::make_filter<size_t, void>(tbb::filter_mode::parallel, [&](size_t si) {
            Levels node = extractSlab(si);
            forEachLevel(node, [&](size_t k, Integrator&) {
                std::unique_ptr<Integrator> mine = std::move(node[k]);
                size_t nl = si, nr = si + 1;
                while (nl != l || nr != r) {
                    const auto [pl, pr] = parentNode(l, r, nl, nr);
                    const size_t pm = mergeSplit(pl, pr);
                    const bool isLeft = nl == pl;
                    if (isLeft) {  // before it may wait: joinLevel parks it otherwise
                        const double start = mClock.seconds();
                        mine->park();
                        timed(nl, nr, start);
                    }
                    std::unique_ptr<Integrator> sibling;
                    {
                        std::lock_guard<std::mutex> lock(waitingMutex);
                        const auto it = waiting.find(isLeft ? std::make_tuple(pm, pr, k) : std::make_tuple(pl, pm, k));
                        if (it == waiting.end()) {
                            waiting.emplace(std::make_tuple(nl, nr, k), std::move(mine));
                            return;
                        }
                        sibling = std::move(it->second);
                        waiting.erase(it);
                    }
                    if (!isLeft) std::swap(mine, sibling);  // the left one absorbs the right one
                    const double start = mClock.seconds();
                    joinLevel(*mine, std::move(*sibling), pl, pr);
                    sibling.reset();
                    timed(pl, pr, start);
                    nl = pl;
                    nr = pr;
                }
                if (k > 0 && wholeTree(l, r)) {
                    uint64_t unfinalized = 0;
                    mine->finish(coarserLevelTarget(mOpt, mine->facesGenerated(), k), mine->facesGenerated(), unfinalized);
                }
                whole[k] = std::move(mine);  // one task per level: no two write the same entry
            });
        }));
    // The run was cancelled, or failed elsewhere: no node is complete.
    const bool complete = std::all_of(whole.begin(), whole.end(), [](const auto& level) { return level != nullptr; });
    if (!complete || tbb::is_current_task_group_canceling()) throw Cancelled("cancelled");
    return whole;
}

// A node's seconds: its slab's extraction or its join, and its parking (park()) if it is a left child;
// a chain's levels join one by one, so theirs add up.
void PipelineRun::timed(size_t l, size_t r, double start)
{
    const double seconds = mClock.seconds() - start;
    std::lock_guard<std::mutex> lock(mTreeMutex);
    const auto same = [&](const Report::TreeNode& n) { return n.firstSlab == l && n.endSlab == r; };
    const auto it = std::find_if(mTree.rbegin(), mTree.rend(), same);
    if (it != mTree.rend()) it->seconds += seconds;
    else mTree.push_back({uint32_t(l), uint32_t(r), seconds});
}

// Siblings [l, m) and [m, r) join: the right one's mesh moves into the left one's, and the vertices
// whose cells all lie in slabs [l, r) become final (the seam between them) and are decimated.
void PipelineRun::join(Levels& left, std::vector<SlabPiece>&& right, size_t l, size_t r) const
{
    if (right.size() != left.size()) throw std::runtime_error("merge tree: a node with " + std::to_string(right.size()) +
                                                              " levels joins one with " + std::to_string(left.size()));
    forEachLevel(left, [&](size_t k, Integrator& level) { joinLevel(level, std::move(right[k]), l, r); });
}

template <typename Right>
void PipelineRun::joinLevel(Integrator& left, Right&& right, size_t l, size_t r) const
{
    left.park();  // every left child goes through park() once before its join, waiting or not
    left.absorbSlab(std::forward<Right>(right), [&](EdgeKey key) { return edgeWithin(key, mOrder, l, r); });
}

// Decimation passes poll the same progress object, so a cancel request stops them too.
void PipelineRun::watch(Decimator& dec)
{
    if (!mProgress) return;
    dec.setInterrupter([this, &dec] {
        std::lock_guard<std::mutex> lock(mProgressMutex);
        return !mProgress->update(double(mDone) / double(mRankBlocks), dec.faceCount());
    });
}

// One slab's blocks: extracted in parallel, integrated (and decimated every batch) in block order.
Levels PipelineRun::extractSlab(size_t si)
{
    const double start = mClock.seconds();
    {
        std::lock_guard<std::mutex> lock(mParkMutex);
        mSlabsStarted = std::max(mSlabsStarted, si + 1);
    }
    auto integ = std::make_unique<Integrator>(mOpt, mRatio, mSlabBatch, uint32_t(si));
    Decimator& dec = integ->decimator();
    dec.setVoxelArea(mVoxelArea);
    watch(dec);
    const Slab& slab = mSlabs[si];
    size_t next = slab.begin;
    const size_t tokens = 4 * std::max<size_t>(1, std::thread::hardware_concurrency());
    // Block meshes live in a ring of `tokens` slots rather than travelling as heap items: at most
    // `tokens` blocks are in flight and the last stage is in order, so block i + tokens never starts
    // before block i is integrated; and a cancelled pipeline leaves nothing behind (TBB does not
    // destroy items that are in flight when a stage throws).
    std::vector<BlockMesh> slots(tokens);
    // Isolated: a thread waiting here runs this slab's blocks only, never another slab's, so no more
    // slabs are in progress than threads (each holds its open seams and live voxels).
    tbb::this_task_arena::isolate([&] {
        tbb::parallel_pipeline(
            tokens,
            indices(next, slab.end) &
                tbb::make_filter<size_t, size_t>(tbb::filter_mode::parallel,
                                                 [&](size_t i) {
                                                     meshBlock(si, i, slots[i % tokens]);
                                                     return i;
                                                 }) &
                tbb::make_filter<size_t, void>(tbb::filter_mode::serial_in_order,
                                               [&](size_t i) { integrateBlock(*integ, slots[i % tokens]); }));
    });
    if (tbb::is_current_task_group_canceling()) throw Cancelled("cancelled");
    integ->finishSlab();
    // Dead entries are dropped before the slab is copied for a coarser level (a left child's as it
    // parks: Integrator::park).
    if (mOpt.lods.size() > 1) integ->compactQueue();
    Levels levels;
    levels.push_back(std::move(integ));
    // A LOD chain's coarser levels continue from the finer one here, slab by slab, in parallel with
    // the other slabs; then every level joins up the tree on its own.
    for (size_t k = 1; k < mOpt.lods.size(); ++k) {
        levels.push_back(levels.back()->coarser(mOpt.lods[k]));
        watch(levels.back()->decimator());
    }
    timed(si, si + 1, start);
    return levels;
}

// Marching Cubes on block i of slab si. Thread-safe. A vertex whose first cell (in block order) lies
// in an earlier slab stays open: that slab holds the other half of its faces.
void PipelineRun::meshBlock(size_t si, size_t i, BlockMesh& m) const
{
    BlockSamples s;
    mVol->sample(mBlocks[i], s, mEarlyReads[i]);
    m.blockIndex = i;
    const auto mm = std::minmax_element(s.values.begin(), s.values.end());
    m.minValue = *mm.first;
    m.maxValue = *mm.second;
    extractBlock(s, mCls, mInfo.indexToWorld, mFlip, m);
    // The block itself is last of the cells around a vertex it finalises; only the first may lie before the slab.
    for (size_t v = 0; v < m.keys.size(); ++v)
        if (m.finalAfterBlock[v] && !edgeWithin(m.keys[v], mOrder, si, mSlabs.size())) m.finalAfterBlock[v] = 0;
    if (mOpt.attributeWeight > 0) mAttributes->sampleFirst(m.positions, m.attribute);
}

// The in-order stage: the block's mesh joins its slab, leaves no block still needs are freed,
// progress is counted.
void PipelineRun::integrateBlock(Integrator& integ, const BlockMesh& m)
{
    integ.add(m);
    releaseSampledLeaves(m.blockIndex);
    std::lock_guard<std::mutex> lock(mProgressMutex);
    mSampled = {std::min(mSampled[0], m.minValue), std::max(mSampled[1], m.maxValue)};
    ++mDone;
    if (mDone == mRankBlocks) {
        // Every block has been sampled (a block counts itself done after its last read): what is left
        // of the grid goes before the top joins and the final pass, where the run has its peak.
        mVol.reset();
        mLeafSamplers.reset();
        mEarlyReads.reset();
        mSweep = {};
        mSweepAt = {};
        malloc_trim(0);
    } else {
        if (mDone % Volume::kTrimEveryBlocks == 0 && !mVol->readsStoredRecords()) mVol->trimInputMapping();
        // Released leaves are small heap objects: give the pages they emptied back.
        if (mDone % kMallocTrimEveryBlocks == 0) malloc_trim(0);
    }
    if (mProgress && (mDone % kProgressEveryBlocks == 0 || mDone == mRankBlocks) &&
        !mProgress->update(double(mDone) / double(mRankBlocks), integ.decimator().faceCount()))
        throw Cancelled("cancelled");
}

// The blocks this process extracts: all of them, or the slabs of its rank.
std::pair<size_t, size_t> PipelineRun::rankBlocks() const
{
    const auto [l, r] = rankSlabRange();
    return l == r ? std::pair<size_t, size_t>{0, 0} : std::pair<size_t, size_t>{mSlabs[l].begin, mSlabs[r - 1].end};
}

std::pair<size_t, size_t> PipelineRun::rankSlabRange() const
{
    if (!mRanks) return {0, mSlabs.size()};
    return rankSlabs(mSlabs.size(), mRanks->rank(), mRanks->ranks());
}

// The first place in mSweep not z/y/x-before `o`, searched from `from`, which is not after `o`:
// galloping on, a few steps for a block nearby where a search of the whole list took 17.
size_t PipelineRun::lowerBoundFrom(const BlockOrigin& o, size_t from) const
{
    const auto before = [](const std::pair<BlockOrigin, uint32_t>& b, const BlockOrigin& x) { return lexBefore(b.first, x, 2); };
    size_t lo = from, step = 1;
    while (lo + step < mSweep.size() && before(mSweep[lo + step], o)) {
        lo += step;
        step *= 2;
    }
    const auto end = mSweep.begin() + std::ptrdiff_t(std::min(mSweep.size(), lo + step + 1));
    return size_t(std::lower_bound(mSweep.begin() + std::ptrdiff_t(lo), end, o, before) - mSweep.begin());
}

// f(leaf, d, j) for the leaves block i samples (block_order.h's sampledLeaf), j their index in the
// list or the list's size where a leaf is no block. A leaf lies at or above block i, so not before it
// in z/y/x order, and each is searched from the one it lies +x, +y or +z of (d without its lowest
// bit): the next block, a row or a layer on.
template <typename F>
void PipelineRun::forSampledLeaves(size_t i, F&& f) const
{
    std::array<size_t, 8> at{};
    at[0] = mSweepAt[i];
    f(mBlocks[i], 0, i);
    for (int d = 1; d < 8; ++d) {
        const BlockOrigin leaf = sampledLeaf(mBlocks[i], d);
        at[size_t(d)] = lowerBoundFrom(leaf, at[size_t(d & (d - 1))]);
        const size_t p = at[size_t(d)];
        f(leaf, d, p < mSweep.size() && mSweep[p].first == leaf ? size_t(mSweep[p].second) : mBlocks.size());
    }
}

void PipelineRun::countLeafSamplers(size_t begin, size_t end)
{
    mRankBlocks = end - begin;
    mLeafSamplers.reset(new std::atomic<uint8_t>[mBlocks.size()]);
    mEarlyReads.reset(new uint8_t[mBlocks.size()]());
    for (size_t j = 0; j < mBlocks.size(); ++j) mLeafSamplers[j].store(0, std::memory_order_relaxed);
    mSweep.resize(mBlocks.size());
    for (size_t j = 0; j < mBlocks.size(); ++j) mSweep[mSweepAt[j]] = {mBlocks[j], uint32_t(j)};
    mSlabsStarted = 0;
    // Each rank counts its own blocks' reads: the scaling model divides this among workers.
    const double start = mClock.seconds();
    tbb::parallel_for(tbb::blocked_range<size_t>(begin, end), [&](const tbb::blocked_range<size_t>& range) {
        for (size_t i = range.begin(); i != range.end(); ++i) {
            const size_t slab = slabOf(i);
            forSampledLeaves(i, [&](const BlockOrigin&, int d, size_t j) {
                if (j < mBlocks.size()) {
                    const bool early = slab + 1 < slabOf(j);
                    mLeafSamplers[j].fetch_add(early ? kEarlySampler + 1 : 1, std::memory_order_relaxed);
                    mEarlyReads[i] |= uint8_t(early) << d;
                }
            });
        }
    });
    mResult.report.secondsSamplers = mClock.seconds() - start;
}

size_t PipelineRun::slabOf(size_t block) const
{
    const auto it = std::upper_bound(mSlabs.begin(), mSlabs.end(), block, [](size_t b, const Slab& s) { return b < s.begin; });
    return size_t(it - mSlabs.begin()) - 1;
}

// Once the last block sampling a leaf is integrated (in whichever slab), the leaf is freed; once the
// last of its early readers is, it is parked.
void PipelineRun::releaseSampledLeaves(size_t i)
{
    const uint8_t early = mEarlyReads[i];
    forSampledLeaves(i, [&](const BlockOrigin& leaf, int d, size_t j) {
        const bool isEarly = (early >> d) & 1;
        if (j >= mBlocks.size()) return;
        const uint8_t step = isEarly ? kEarlySampler + 1 : 1;
        const uint8_t left = uint8_t(mLeafSamplers[j].fetch_sub(step, std::memory_order_acq_rel) - step);
        if ((left & (kEarlySampler - 1)) == 0) mVol->releaseLeaf(leaf);
        else if (isEarly && left < kEarlySampler) parkOrKeep(j, leaf);
    });
}

// The leaf's other readers are in the slab before its own or later: parked if none of those has
// started (slabs start in order), else kept for them.
void PipelineRun::parkOrKeep(size_t leaf, const BlockOrigin& origin)
{
    std::lock_guard<std::mutex> lock(mParkMutex);
    if (mSlabsStarted < slabOf(leaf)) mVol->parkLeaf(origin);
}

// What a rank sends up the tree: the seconds and peak memory of every rank below it, then its node.
std::vector<char> PipelineRun::rankMessage(std::vector<SlabPiece>&& levels) const
{
    std::vector<std::array<double, 4>> ranks = mRanksBelow;
    ranks.insert(ranks.begin(), {mClock.seconds(), peakRssMb(), 0.0, mSetupCpu});
    std::vector<char> out;
    const uint64_t n = ranks.size();
    out.insert(out.end(), reinterpret_cast<const char*>(&n), reinterpret_cast<const char*>(&n) + sizeof n);
    out.insert(out.end(), reinterpret_cast<const char*>(ranks.data()), reinterpret_cast<const char*>(ranks.data() + n));
    // Then the node's levels, each as its length and its bytes.
    const uint64_t count = levels.size();
    out.insert(out.end(), reinterpret_cast<const char*>(&count), reinterpret_cast<const char*>(&count) + sizeof count);
    for (SlabPiece& level : levels) {
        const size_t at = out.size();
        out.resize(at + sizeof(uint64_t));
        writePieceBytes(std::move(level), out);
        const uint64_t length = out.size() - at - sizeof(uint64_t);
        std::memcpy(out.data() + at, &length, sizeof length);
    }
    const double bytes = double(out.size());  // this rank's entry: the message itself
    std::memcpy(out.data() + sizeof n + 2 * sizeof(double), &bytes, sizeof bytes);
    return out;
}

std::vector<SlabPiece> PipelineRun::readRankMessage(const std::vector<char>& bytes)
{
    uint64_t n = 0;
    if (bytes.size() < sizeof n) throw std::runtime_error("merge tree message: bytes end early");
    std::memcpy(&n, bytes.data(), sizeof n);
    const size_t head = sizeof n + n * sizeof(std::array<double, 4>);
    if (n > bytes.size() || bytes.size() < head) throw std::runtime_error("merge tree message: bytes end early");
    std::vector<std::array<double, 4>> ranks(n);
    std::memcpy(ranks.data(), bytes.data() + sizeof n, n * sizeof(std::array<double, 4>));
    mRanksBelow.insert(mRanksBelow.end(), ranks.begin(), ranks.end());
    size_t at = head;
    const auto count = [&] {
        uint64_t x = 0;
        if (bytes.size() - at < sizeof x) throw std::runtime_error("merge tree message: bytes end early");
        std::memcpy(&x, bytes.data() + at, sizeof x);
        at += sizeof x;
        return x;
    };
    std::vector<SlabPiece> levels(count());
    for (SlabPiece& level : levels) {
        const uint64_t length = count();
        if (length > bytes.size() - at) throw std::runtime_error("merge tree message: bytes end early");
        level = readPieceBytes(bytes.data() + at, length);
        at += length;
    }
    return levels;
}

// The tree's root holds the whole surface: the final pass runs on it, and the report is completed.
Result PipelineRun::finalPass()
{
    Report& rep = mResult.report;
    const double finalStart = mClock.seconds();
    Integrator& whole = *mRoot.front();
    const uint64_t facesGenerated = whole.facesGenerated();
    const SlabStats slabs = whole.stats();
    rep.decimations = slabs.decimations;
    rep.maxUncontractibleFaces = slabs.maxUncontractibleFaces;
    rep.trace = slabs.trace;
    rep.maxIntermediateFaces = std::max(slabs.maxIntermediateFaces, uint64_t(whole.decimator().faceCount()));

    if (mOpt.targetFaces == 0 || mCountRuns.stride > 1) rep.facesFull = facesGenerated;
    if (rep.facesFull == 0) throw noSurface();
    rep.ratio = mRatio;
    rep.facesTarget = mOpt.targetFaces > 0 ? std::min<uint64_t>(mOpt.targetFaces, rep.facesFull)
                                           : uint64_t(std::llround(mRatio * double(rep.facesFull)));
    std::vector<uint64_t> unfinalized(mRoot.size(), 0);
    const size_t seamVertices = whole.decimator().openVertices();
    rep.facesRetired = whole.decimator().retiredFaces();
    const size_t traced = slabs.trace.size();
    const auto parallelSeconds = [&] {
        double s = 0.0;
        for (const auto& level : mRoot) s += level->decimator().parallelSeconds();
        return s;
    };
    const double parallelBefore = parallelSeconds();
    // A chain's levels get their final passes at once (those that have not had it at the root).
    forEachLevel(mRoot, [&](size_t k, Integrator& level) {
        if (!level.finished()) level.finish(levelTarget(mOpt, rep, k), facesGenerated, unfinalized[k]);
    });
    rep.secondsFinalParallel = parallelSeconds() - parallelBefore;
    rep.unfinalizedAtEnd = unfinalized.front() - seamVertices;
    QueueWork work;
    for (const auto& level : mRoot) work += level->stats().work;
    rep.queuePops = work.pops;
    rep.queueDead = work.dead;
    rep.queueStale = work.stale;
    rep.collapseAttempts = work.attempts;
    rep.collapses = work.collapses;
    const SlabStats all = whole.stats();
    rep.trace.insert(rep.trace.end(), all.trace.begin() + traced, all.trace.end());
    rep.decimations += all.trace.size() - traced;
    // Nodes absorbed into the root keep what their own passes accepted.
    rep.maxErrorAccepted = std::max(all.maxErrorAccepted, whole.decimator().maxErrorAccepted());
    mAttributes->load();
    if (mOpt.lods.empty()) {
        mResult.mesh = takeLevelMesh(whole, rep);
        mResult.mesh.attributes = mAttributes->sample(mResult.mesh.points);
    } else {
        // Each level is made from the one before, handed over and let go; the last one is the result.
        mResult.mesh = makeLevels(mRoot, rep, mOpt, *mAttributes, mClock);
    }
    // The result is the last level's (the only one without a chain).
    const Integrator& last = *mRoot.back();
    rep.componentsDropped = last.componentsDropped();
    rep.componentsPruned = last.componentsPruned();
    if (mResult.mesh.triangles.empty()) {  // every component was below the minimum area
        std::ostringstream s;
        s << mPath << ": every component of the surface in grid '" << mInfo.gridName << "' has an area below "
          << mOpt.minComponentArea;
        throw EmptySurfaceError(s.str());
    }
    rep.secondsFinal = mClock.seconds() - finalStart;
    rep.facesOut = mResult.mesh.triangles.size();
    rep.vertsOut = mResult.mesh.points.size();
    rep.stoppedBy = stopReason(rep.facesOut, rep.facesTarget, last.boundHeld());
    return rankReport();
}

// The report's run-wide numbers; with ranks, each rank's seconds and peak memory (rank 0 first).
Result PipelineRun::rankReport()
{
    Report& rep = mResult.report;
    rep.seconds = mClock.seconds();
    rep.peakRssMb = peakRssMb();
    rep.ranks = mRanks ? mRanks->ranks() : 1;
    if (mRanks) {
        std::vector<std::array<double, 4>> ranks = mRanksBelow;
        ranks.insert(ranks.begin(), {rep.seconds, rep.peakRssMb, 0.0, mSetupCpu});
        for (const auto& r : ranks) {
            rep.rankSeconds.push_back(r[0]);
            rep.rankPeakRssMb.push_back(r[1]);
            rep.rankBytesSent.push_back(r[2]);
            rep.rankSetupCpuSeconds.push_back(r[3]);
        }
    }
    rep.tree = std::move(mTree);
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

Result runPipeline(const VolumeOpener& open, const std::string& path, const Options& opt, Progress* progress,
                   RankChannel* ranks)
{
    PipelineRun run(path, opt, progress, ranks);
    try {
        checkOptions(opt);
        run.openVolume(open);
        run.chooseIso();
        run.listBlocks();
        run.splitSlabs();
        run.keepOwnLeaves();
        run.setupDone();
        run.countFacesForTarget();
    } catch (const PeerFailed&) {
        run.agreeAmongRanks({});  // another rank failed first: agree() reports its message
        throw;
    } catch (const std::exception& e) {
        run.failBeforeRange();
        run.failBeforeBlocks();
        run.agreeAmongRanks(e.what());
        throw;
    }
    run.agreeAmongRanks({});
    if (run.sampleTooCoarse()) {
        try {
            run.countFacesExactly();
        } catch (const std::exception& e) {
            run.agreeAmongRanks(e.what());
            throw;
        }
        run.agreeAmongRanks({});
    }
    run.setTarget();
    if (!run.runTree()) return run.rankReport();
    return run.finalPass();
}

} // namespace

Result simplifyVolume(const VolumeOpener& open, const std::string& name, const Options& opt, Progress* progress,
                      RankChannel* ranks)
{
    // Every input error names the input, whichever stage found it.
    try {
        // A thread count applies to this run only: an arena of its own, not a process-wide limit
        // that would hold every other TBB user of a host (Blender, Houdini, Python) while it runs.
        if (opt.threads <= 0) return runPipeline(open, name, opt, progress, ranks);
        // No more than the cores this process may use (mpirun binds each rank to its own): TBB would
        // warn and run with fewer anyway.
        tbb::task_arena arena(std::min(opt.threads, tbb::info::default_concurrency()));
        return arena.execute([&] { return runPipeline(open, name, opt, progress, ranks); });
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
