// The decimation schedule of the paper's section 4.2, for one slab: blocks are integrated in order and
// the mesh is decimated every few batches, so that it never holds more than R*F + B faces.
#pragma once
#include "core/decimator.h"
#include "core/edge_key.h"
#include "core/marching_cubes.h"
#include "vdb_isosimp/vdb_isosimp.h"

#include <algorithm>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

namespace vdb_isosimp {

// What one slab's integrator measured; merged into the Report in slab order.
struct SlabStats {
    uint64_t decimations = 0, maxIntermediateFaces = 0, maxUncontractibleFaces = 0;
    double maxErrorAccepted = 0.0;  // of the slabs' passes (a decimator is emptied when its node joins)
    QueueWork work;                 // what their decimators' queues did (Decimator::work)
    std::vector<DecimationRecord> trace;

    // Adds a merged slab's numbers: the peaks add up (the slabs may run at once).
    void add(const SlabStats& o)
    {
        decimations += o.decimations;
        maxIntermediateFaces += o.maxIntermediateFaces;
        maxUncontractibleFaces += o.maxUncontractibleFaces;
        maxErrorAccepted = std::max(maxErrorAccepted, o.maxErrorAccepted);
        work += o.work;
        trace.insert(trace.end(), o.trace.begin(), o.trace.end());
    }
};

// What a finished node of the merge tree hands to its parent: its mesh, the faces its slabs
// generated, and what their integrators measured.
struct SlabPiece {
    MeshPiece mesh;
    uint64_t facesGenerated = 0;
    SlabStats stats;
    bool roomSpent = false;  // its last pass went to the rate without room (Options::retireAboveFaces)
};

// Serial, in-order stage of one slab: integration and the decimation schedule of the paper's
// section 4.2, with B faces per batch, one step beyond it: half of B is deferral room. A pass runs
// every B/2 new faces and stops B/2 above the paper's target F_t, so the costliest collapses of a pass
// wait in the queue, where a later pass (the final one at the latest) weighs them against the rest of
// the surface. The intermediate mesh keeps the paper's bound, F_t + B. (A batch held to F_t pays for
// the face budget with its own sharpest features even where another batch has cheaper collapses.)
// Near the root the room is spent: a node of Options::retireAboveFaces faces or more is decimated to
// F_t at its join, and once both sides of a join have been, no room is owed anywhere below it: the
// interior of the joined surface cannot change again but for the collapses near its seams, and it is
// retired (Decimator::retireInterior), so the top of the tree holds seam bands, not the surface.
class Integrator {
public:
    Integrator(const Options& o, double ratio, uint64_t batch, uint32_t slab)
        : mOpt(o), mRatio(ratio), mBatch(batch), mDefer(batch / 2), mSlab(slab),
          mRetireAbove(o.retireAboveFaces)
    {
        // With an error bound the bound keeps early batches from losing detail; the initial phase,
        // which decimates whenever the mesh exceeds B, would run at every block once the bound holds
        // the mesh above B.
        mInitial = ratio < o.initialRatio && !(o.maxError > 0);
        if (o.maxError > 0) mDec.setMaxError(o.maxError);
        if (o.attributeWeight > 0) mDec.setAttributeWeight(o.attributeWeight);
    }

    void add(const BlockMesh& b)
    {
        const uint64_t incoming = b.triangles.size();
        if (incoming == 0 && b.keys.empty()) return;
        mCompacted = false;
        if (mInitial) {
            // Initial phase: let the intermediate mesh grow to B faces, then decimate it at rate R_i,
            // until the regular target catches up (avoids over-decimating the first batches). Never
            // below the regular target: the final mesh must still be able to reach R*F.
            if (mDec.faceCount() + incoming > mBatch && mDec.faceCount() > 0) {
                const uint64_t initial = phaseTarget(double(mDec.faceCount()), mOpt.initialRatio);
                const uint64_t regular = batchTarget(double(mFacesGenerated));
                if (regular >= initial) mInitial = false;
                decimate(std::max(initial, regular));
                mSinceLast = 0;
            }
        } else if (mSinceLast + incoming > mBatch - mDefer && mSinceLast > 0) {
            decimate(batchTarget(double(mFacesGenerated)));
            mSinceLast = 0;
        }
        mDec.addBlock(b);
        mFacesGenerated += incoming;
        mSinceLast += incoming;
        mStats.maxIntermediateFaces = std::max<uint64_t>(mStats.maxIntermediateFaces, mDec.faceCount());
    }

    // The last pass over the whole (merged) surface: every vertex is final now.
    void finish(uint64_t targetFaces, uint64_t facesGenerated, uint64_t& unfinalized)
    {
        unpark();
        mFinished = true;
        mFacesGenerated = facesGenerated;  // the whole surface's, merged slabs included
        mAbsorbedFaces = 0;
        // The merged nodes' numbers join this node's own first, so the final pass's records end the
        // trace (stats() lists a node's own records before those of the nodes it absorbed).
        mStats.add(mAbsorbed);
        mAbsorbed = SlabStats{};
        unfinalized = mDec.finalizeRemaining();
        // The merged queue holds every slab's edges plus the welded seam's.
        reach(targetFaces);
    }

    // Decimates the finished surface to `targetFaces`; called again with smaller targets, it makes
    // the next levels of a LOD chain from the previous one.
    void reach(uint64_t targetFaces)
    {
        decimate(targetFaces);
        // Collapses refused earlier (link condition, fold-overs) may be legal now that the faces around
        // them changed: retry until stuck. Then, only if still above target, allow larger normal turns
        // step by step, unless an error bound is what stops the collapses: folds do not bring the
        // surface closer.
        const bool bounded = mOpt.maxError > 0;
        for (double turn : {Decimator::kDefaultMinNormalCos, 0.0, -0.3, -0.6}) {
            if (bounded && turn != Decimator::kDefaultMinNormalCos) break;
            mDec.setMaxNormalTurn(turn);
            if (mDec.faceCount() <= targetFaces) break;
            // decimateTo retries the refused pairs whose faces changed since, until a pass collapses
            // nothing; a relaxed turn also brings back the pairs refused for folding a face. The
            // others failed the link condition, which no turn changes: a full requeue per step tried
            // ~390k of them again on noise 448^3 at R = 0.01 to find ~2k collapses (0.7 s each step).
            // Under a bound one pass is enough: edges refused for their error come back through the
            // refused list once the faces around them change.
            if (turn != Decimator::kDefaultMinNormalCos) mDec.retryFolds();
            while (mDec.decimateTo(targetFaces) > 0 && mDec.faceCount() > targetFaces && !bounded) {
            }
        }
        mDec.setMaxNormalTurn(Decimator::kDefaultMinNormalCos);
        // Below R = 1, no zero-area face may survive (R = 1 is the exact Marching Cubes surface).
        if (targetFaces < mFacesGenerated) mDec.removeDegenerateFaces();
        // Still above target (more than 1%): the surface is mostly small closed components that no
        // collapse can shrink further; the smallest ones go, so the face count the user asked for holds
        // (not under an error bound: a dropped component moves the surface by its own size).
        if (!bounded && double(mDec.faceCount()) > 1.01 * double(targetFaces))
            mComponentsDropped += mDec.dropSmallComponents(targetFaces);
        mBoundHeld = bounded && mDec.faceCount() > targetFaces && mDec.boundRefusesAnEdge();
        // Floaters the caller asked to lose go last, so they take no part in the decimation's choices.
        if (mOpt.minComponentArea > 0) mComponentsPruned = mDec.pruneComponents(mOpt.minComponentArea);
    }

    // The same slab one level down a LOD chain: a copy of this mesh decimated like a last batch at the
    // coarser rate, so the coarser level continues this level's collapses inside the slab (in
    // parallel with the other slabs) and then joins and finishes like any slab. The copy keeps this
    // decimator's settings; its interrupter is the caller's to set.
    std::unique_ptr<Integrator> coarser(double ratio) const
    {
        auto c = std::make_unique<Integrator>(mOpt, ratio, mBatch, mSlab);
        c->mDec = mDec;
        c->mWorkSeen = mDec.work();  // the copy counts its own passes only
        c->mFacesGenerated = mFacesGenerated;
        c->mAbsorbedFaces = mAbsorbedFaces;
        c->mInitial = false;
        // Region by region: the copy is a whole slab already at the finer rate, and its cheapest
        // collapses lie all over it.
        const uint64_t target = c->batchTarget(double(c->facesGenerated()));
        const uint64_t excess = c->mDec.faceCount() > target ? c->mDec.faceCount() - target : 0;
        c->decimate(target, std::max<uint64_t>(1, excess / kRegionFaces));
        c->compactQueue();
        c->mStats.maxErrorAccepted = c->mDec.maxErrorAccepted();
        return c;
    }

    // End of a slab: its last batch is decimated like the others (in parallel with the other slabs),
    // so the serial final pass is left with the seams. The initial phase ends here too: it belongs to
    // a slab's first batches, and a slab too small to leave it (under B faces, as at a corner of the
    // volume) kept every node it is the first slab of from decimating at its joins, so an undecimated
    // mesh went up the tree's left edge to the root.
    void finishSlab()
    {
        mInitial = false;
        if (mSinceLast > 0) decimate(batchTarget(double(mFacesGenerated)));
        mSinceLast = 0;
        mStats.maxErrorAccepted = mDec.maxErrorAccepted();
        mDec.seal();
    }

    // This node's mesh and numbers, for its parent in the merge tree; the integrator is left empty.
    SlabPiece takePiece()
    {
        SlabPiece p = handOver();
        p.mesh = mDec.takePiece();
        return p;
    }

    // The sibling node of the merge tree is done: its mesh joins this one, and the open vertices that
    // `closes` accepts (the seam between them, welded by key) become final and are decimated like a
    // batch while other slabs run, instead of waiting for the serial final pass. The queue is left
    // as the pass leaves it: the caller compacts a node that goes on up the tree.
    void absorbSlab(SlabPiece&& sibling, const std::function<bool(EdgeKey)>& closes)
    {
        unpark();
        mDec.absorb(std::move(sibling.mesh));
        joined(sibling, closes);
    }
    // The same for a sibling in this process: its mesh is read in place, not copied into a piece
    // first (the same mesh either way); the sibling is left empty.
    void absorbSlab(Integrator&& sibling, const std::function<bool(EdgeKey)>& closes)
    {
        const SlabPiece numbers = sibling.handOver();
        unpark();
        mDec.absorb(std::move(sibling.mDec));
        joined(numbers, closes);
    }

    // A finished left child of the merge tree, until its sibling is done (near the end of a run the
    // nodes of the tree's left spine wait for the last slabs): where parks() says so, its mesh is held
    // as a piece, 12 bytes a face and 112 a vertex against 24 and 120 with adjacency, without the slots
    // of dead faces and vertices. Otherwise its queue drops its dead entries, as the piece does, before
    // the sibling's queue joins it. (A right child's queue is drained by its parent's take, which drops
    // them itself, and the root's only serves the final pass, which skips them as it pops: compacting
    // there took 0.45 s of the serial top of the tree on noise 448^3 at R = 0.2.) Every left child
    // goes through here once before its join, waiting or not, so the mesh does not depend on which
    // thread or rank finished first; absorbSlab takes the piece back.
    void park()
    {
        if (mParked) return;
        if (parks()) mParked = std::make_unique<MeshPiece>(mDec.park());
        else compactQueue();
    }

    // Drops the queue's dead entries; a second call before the next pass finds none and does nothing
    // (a LOD chain's slab is compacted before its copies and may come here again as a left child).
    void compactQueue()
    {
        if (mCompacted) return;
        mDec.compactQueue();
        mCompacted = true;
    }

    // Parked where the open seams are at least an eighth of the vertices: at low rates (R = 0.02 on
    // noise 448^3 every node, 14-56 % open) the full-resolution seams are most of what waits, and the
    // run's peak is the waiting nodes'; at high rates the large nodes near the root (2-13 % open at
    // R = 0.2) hold a decimated interior, the peak is the root's own mesh, and a copy there only costs
    // time and the unpark's transient (docs/perf.md).
    bool parks() const { return 8 * mDec.openVertices() >= mDec.vertexCount(); }

    uint64_t facesGenerated() const { return mFacesGenerated + mAbsorbedFaces; }
    bool finished() const { return mFinished; }
    size_t faceCount() const { return mDec.faceCount(); }
    uint64_t componentsDropped() const { return mComponentsDropped; }
    uint64_t componentsPruned() const { return mComponentsPruned; }
    // The last reach() stopped above its target where the error bound, not the topology, refused a collapse.
    bool boundHeld() const { return mBoundHeld; }
    Decimator& decimator() { return mDec; }
    // Its own decimations and those of every slab merged into it, in merge order.
    SlabStats stats() const
    {
        SlabStats s = mStats;
        s.work += mDec.work() - mWorkSeen;
        s.add(mAbsorbed);
        return s;
    }

private:
    // F_t = (F - F_u) * rate + F_u: only the contractible part of the mesh is held to the rate.
    uint64_t phaseTarget(double faces, double rate) const
    {
        const double fu = double(mDec.uncontractibleFaces());
        return uint64_t(std::max(0.0, faces - fu) * rate + fu);
    }

    // Where a pass before the final one stops: F_t plus the deferral room.
    uint64_t batchTarget(double faces) const { return phaseTarget(faces, mRatio) + mDefer; }

    // Faces a region of a coarser level's copy removes (coarser()): small enough that a region's
    // records stay in cache, large enough that a region is more than its boundary (docs/perf.md).
    static constexpr uint64_t kRegionFaces = 2000;

    // What a node hands its parent besides its mesh (takePiece, absorbSlab): the faces its slabs
    // generated and the numbers of its passes. The mesh is the caller's to take next.
    SlabPiece handOver()
    {
        unpark();
        mStats.maxErrorAccepted = std::max(mStats.maxErrorAccepted, mDec.maxErrorAccepted());
        mStats.work += mDec.work() - mWorkSeen;
        mWorkSeen = {};  // the decimator is emptied next, its count at zero
        SlabPiece p{MeshPiece{}, mFacesGenerated + mAbsorbedFaces, std::move(mStats), mRoomSpent};
        p.stats.add(mAbsorbed);
        return p;
    }

    // absorbSlab, once the sibling's mesh is in: the seam becomes final and is decimated.
    void joined(const SlabPiece& sibling, const std::function<bool(EdgeKey)>& closes)
    {
        mDec.finalizeOpen(closes);
        mAbsorbedFaces += sibling.facesGenerated;
        mAbsorbed.add(sibling.stats);
        // Not without open vertices: that is the root (or, rarely, a node whose surface meets none of its
        // neighbours'), where the final pass follows at once, so retiring would only lengthen the serial
        // top of the tree (0.13-0.18 s of noise 448^3's root join at R = 0.2, against 0.12 s for the rest).
        if (mRoomSpent && sibling.roomSpent && mDec.openVertices() > 0) mDec.retireInterior(kRetireRings, mOpt.minComponentArea);
        mRoomSpent = mRetireAbove > 0 && mDec.faceCount() >= mRetireAbove;
        const double faces = double(mFacesGenerated + mAbsorbedFaces);
        decimate(mRoomSpent ? phaseTarget(faces, mRatio) : batchTarget(faces));
    }
    // Rings kept live around a retirement's seams: the seam's pass and the next joins' collapses reach
    // a few rings into a node (3 rings cost noise 448^3 +2.7 % RMS at R = 0.2, 6 rings +2.1 %, 12 rings
    // +1.9 %; docs/perf.md).
    static constexpr size_t kRetireRings = 6;

    void unpark()
    {
        mCompacted = false;  // the piece's entries join the queue
        if (!mParked) return;
        mDec.absorb(std::move(*mParked));
        mParked.reset();
    }

    void decimate(uint64_t target, size_t regions = 1)
    {
        mCompacted = false;
        DecimationRecord rec{mFacesGenerated, mDec.faceCount(), 0, mDec.uncontractibleFaces(), target, mSlab};
        mStats.maxUncontractibleFaces = std::max<uint64_t>(mStats.maxUncontractibleFaces, rec.uncontractible);
        mDec.decimateRegionByRegion(target, regions);
        rec.facesAfter = mDec.faceCount();
        mStats.trace.push_back(rec);
        ++mStats.decimations;
    }

    const Options& mOpt;
    double mRatio;
    uint64_t mBatch, mDefer;
    uint32_t mSlab;
    uint64_t mRetireAbove;   // 0: no room is spent early, nothing retires
    bool mRoomSpent = false; // this node's last pass went to F_t without room
    Decimator mDec;
    std::unique_ptr<MeshPiece> mParked;  // park()
    bool mCompacted = false;             // compactQueue() ran, and no pass or absorb since
    SlabStats mStats;
    bool mInitial = false;
    bool mFinished = false;  // finish() ran: the mesh is at its final target
    bool mBoundHeld = false;
    uint64_t mFacesGenerated = 0, mSinceLast = 0, mComponentsDropped = 0, mComponentsPruned = 0;
    uint64_t mAbsorbedFaces = 0;  // faces generated by slabs merged into this one (absorbSlab)
    SlabStats mAbsorbed;          // and their numbers
    QueueWork mWorkSeen;          // mDec's work when this integrator took it over (a LOD copy's is its finer level's)
};

} // namespace vdb_isosimp
