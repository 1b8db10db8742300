// Incremental QEM decimator: the intermediate iso-surface, grown block by block and decimated in place.
//
// Garland & Heckbert, "Surface simplification using quadric error metrics" (1997), applied on the fly
// as in Hou & Chen, "On-the-fly simplification of large iso-surfaces with per-cube vertex modifiability
// detection": quadrics are accumulated as faces arrive and kept across batches; one persistent priority
// queue holds the edges whose two ends are final (modifiability.h), with lazy invalidation by per-vertex
// version numbers. A collapse moves the survivor to the cheapest of the quadric's optimum, the best point
// of the edge, its ends and midpoint that keeps every face valid, and is charged that placement's cost;
// it is refused when it would break the link condition (the mesh stays 2-manifold), or when no
// placement avoids flipping or degenerating a face.
#pragma once
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <functional>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/attribute_quadric.h"
#include "core/chunked_vector.h"
#include "core/marching_cubes.h"
#include "core/radix_queue.h"
#include "core/quadric.h"
#include "vdb_isosimp/mesh.h"

namespace vdb_isosimp {

// Why a collapse was refused: it would break the link condition (the surface's topology), every
// placement would fold or degenerate a face, or it would move the surface by more than the error bound.
enum class Refusal : uint8_t { Topology = 0, Folds = 1, Bound = 2 };

// The retired part of a surface (Decimator::retireInterior): points in float, as the output has them,
// and faces, in chunks, so a merge or the output's collection frees them as it reads them.
struct RetiredMesh {
    ChunkedVector<std::array<float, 3>> points;
    ChunkedVector<std::array<uint32_t, 3>> triangles;
};

// A decimator's mesh as a merge hands it on (Decimator::takePiece): alive vertices renumbered densely
// in id order, faces in id order, the open vertices by edge key, and the queue and refused pairs
// that name live vertices. absorb() reads nothing else of the other side, so absorbing a piece made
// here or one that travelled to another process (piece_bytes.h) gives the same mesh.
struct MeshPiece {
    struct Vertex {
        std::array<double, 3> p;
        Quadric q;
        bool final;
    };
    struct Queued {
        uint32_t costBits, a, b;
        bool stale;  // an end changed since it was queued: re-evaluated when popped
    };
    ChunkedVector<Vertex> vertices;
    ChunkedVector<std::array<uint32_t, 3>> faces;
    std::vector<std::pair<EdgeKey, uint32_t>> open;  // sorted by key
    ChunkedVector<Queued> queue;                      // in the queue's array order
    uint32_t forgetFromBits = 0;  // non-zero: edges costing this (float bits) or more are not in `queue`
    // Refused pairs: their faces are all there (both ends are final), so a merge changes nothing
    // around them and they stay refused until their faces change, remembering why.
    struct Refused {
        uint32_t a, b;
        Refusal why;
    };
    std::vector<Refused> refused;
    // Per vertex, only where the decimator keeps them: the drift under an error bound, and the
    // attribute quadric (written around the vertex) with an attribute weight.
    ChunkedVector<float> drift;
    ChunkedVector<AttributeQuadric> attributes;
    // The retired part of the surface (Decimator::retireInterior) and, per pinned vertex (its number
    // here, in order), its point there.
    RetiredMesh retired;
    std::vector<std::pair<uint32_t, uint32_t>> pinned;
};

// What decimateTo() did, counted per queue entry popped: every pop is an entry of a dead vertex, a
// stale entry re-evaluated and queued again, or a collapse attempted (which may collapse). The same
// work for any thread or rank count (the merge tree is fixed), so unlike seconds it compares two
// builds exactly on a noisy machine.
struct QueueWork {
    uint64_t pops = 0, dead = 0, stale = 0, attempts = 0, collapses = 0;

    QueueWork& operator+=(const QueueWork& o)
    {
        pops += o.pops;
        dead += o.dead;
        stale += o.stale;
        attempts += o.attempts;
        collapses += o.collapses;
        return *this;
    }
    QueueWork operator-(const QueueWork& o) const
    {
        return {pops - o.pops, dead - o.dead, stale - o.stale, attempts - o.attempts, collapses - o.collapses};
    }
};

class Decimator {
public:
    // Welds the block's vertices to the open frontier by edge key, adds its faces and their quadrics,
    // then marks the block's final vertices and queues the edges that became contractible.
    void addBlock(const BlockMesh& block);

    // Collapses the cheapest contractible edges until at most `targetFaces` faces remain or no legal
    // collapse is left. Returns the number of collapses made.
    size_t decimateTo(size_t targetFaces);
    // decimateTo, region by region: the live vertices are cut along the mesh's longest axis into
    // `regions` runs of equal counts; a queued edge joins the queue when the later region of its two
    // ends comes up, and each region ends once its share of the faces to remove is gone (collapses may
    // still reach back into the regions before it). For a pass over a whole finished mesh: in cost
    // order alone, consecutive collapses land anywhere in it, each reading records far from the last
    // one's; a region's records stay in cache between its collapses. One region is decimateTo.
    size_t decimateRegionByRegion(size_t targetFaces, size_t regions);

    // Moves the mesh out into a piece for a merge (dead queue entries dropped first); this decimator
    // is left empty. Each part is freed as soon as it is copied: the merges are the peak of a run.
    MeshPiece takePiece();
    // The same, but this decimator keeps its settings and counts (normal turn, voxel area, error
    // bound, attribute weight, interrupter, work done), so absorbing the piece back continues it.
    MeshPiece park();
    // Adds a piece's mesh to this one (slab merge). Open vertices with the same edge key are welded
    // and their quadrics summed; the piece is consumed. Its queued edges come along; edges at welded
    // vertices are queued when they are finalised (finalizeOpen, finalizeRemaining).
    void absorb(MeshPiece&& piece);
    // The same as absorb(other.takePiece()), read straight from the other decimator's arrays (a merge
    // in one process): the same mesh and queue, without a copy of the other side in between. `other`
    // is left empty.
    void absorb(Decimator&& other);

    // Drops queue entries that no longer name an edge and releases the spare capacity (before a merge,
    // where every slab's queue is copied).
    void compactQueue();
    size_t queued() const { return mHeap.size(); }

    // End of the volume: every vertex still open becomes final (none should remain in an unbounded
    // domain; the count is returned so tests can check it).
    size_t finalizeRemaining();
    // The open vertices whose edge key `which` accepts become final (in id order); returns how many.
    size_t finalizeOpen(const std::function<bool(EdgeKey)>& which);

    // Collapses the cheapest legal edge of every zero-area face left over (area at most 1e-12 of the
    // squared bounding-box diagonal: coincident vertices where voxels sit at the iso-value), and drops
    // tiny components that are flat all over (no area, no volume). Returns how many remain.
    size_t removeDegenerateFaces();
    // Retires the interior of a finished node of the merge tree: every face whose corners are all more
    // than `rings` rings from an open vertex and from the seam the last finalizeOpen closed leaves the
    // decimator for the retired mesh, 12 bytes a face and 12 a point (float, as the output has them),
    // against ~120 bytes a face here. Nothing collapses there again, so a retired face is one of the
    // output's: its corners that still have faces here stay, pinned (never moved, never queued). Not
    // retired: faces near one that is or may become zero-area (so removeDegenerateFaces can still fix
    // it), and components of fewer than kRetireComponentFaces faces or less area than `minComponentArea`
    // (the minimal closed blobs of noisy data have a few faces, and the whole-component clean-ups
    // remove them most: a retired one costs those a rewrite of the retired mesh). The freed slots are
    // filled by the next absorb. Returns how many faces were retired.
    size_t retireInterior(size_t rings, double minComponentArea);
    static constexpr size_t kRetireComponentFaces = 32;
    size_t retiredFaces() const { return mRetired.triangles.size(); }

    // Seconds this decimator spent in the parts of a final pass that run on all threads:
    // removeDegenerateFaces' scan over every face and takeMesh's collection of the output mesh (the
    // report keeps them apart for the scaling model).
    double parallelSeconds() const { return mParallelSeconds; }

    // Last resort when edge collapses cannot reach the target (many small closed components, each
    // already minimal, as in noisy CT data): removes whole components, smallest area first, never the
    // largest one, until at most `targetFaces` remain. Returns the number of components removed.
    size_t dropSmallComponents(size_t targetFaces);

    // Floater clean-up: removes every component whose area (in the units of the positions, squared)
    // is below `minArea`, the largest one too. Returns the number of components removed.
    size_t pruneComponents(double minArea);

    // Requeues every contractible edge: edges refused earlier may have become legal since.
    void requeueAll();
    // Sends the pairs refused because every placement folded or degenerated a face back to the queue,
    // after the normal turn was relaxed (setMaxNormalTurn): those may pass now. Pairs the link
    // condition refused keep waiting for a change of the faces around an end, which the turn cannot
    // make (on a stuck noise mesh they are ~99 % of the refused pairs).
    void retryFolds();

    // Largest turn of a face normal a collapse may cause, as a cosine: by default about 80 degrees, so
    // no face flips or folds onto its neighbours. The final pass relaxes it when small closed
    // components (noise, scans) would otherwise keep the mesh above its target.
    static constexpr double kDefaultMinNormalCos = 0.17;
    void setMaxNormalTurn(double cosine) { mMinNormalCos = cosine; }

    // Area of a voxel's face in the units of the positions (the grid's transform; default: index
    // space). Faces count with their area in the error quadrics, but at least 0.25 of this (addBlock);
    // a vertex whose faces add up to less than 2 of this has its quadric scaled up to that weight when
    // it becomes final (finalize).
    void setVoxelArea(double area)
    {
        mMinPlaneWeight = kMinPlaneWeight * area;
        mMinVertexWeight = kMinVertexWeight * area;
    }

    // Error bound, in the units of the positions: a collapse whose estimated surface displacement
    // exceeds it is refused (and retried only once the faces around an end change). The estimate is
    // the area-weighted RMS distance of the placement from the planes merged into the edge's two
    // quadrics, sqrt(cost / weight), where weight, the trace of the quadric's 3x3 part, is the sum of
    // the plane weights (each face's area, at least 0.25 voxel faces, and each vertex at least 2); under a bound, also the distance
    // of both ends from the faces the collapse leaves (fanDistance). Infinity (default): no bound.
    void setMaxError(double error) { mMaxError = error; }
    // Queues of more entries than this keep no entry above the cost a pass is likely to reach; the
    // edges are listed again when needed. The same collapses either way (tests lower it to check so).
    void setForgetAboveEntries(size_t entries) { mForgetAbove = entries; }
    // Weight W of an attribute's error against the geometric error (attribute units per world unit):
    // with W > 0 each face also adds an attribute quadric (attribute_quadric.h) from the values of
    // BlockMesh::attribute at its corners, and a collapse costs its geometric error plus W^2 times its
    // attribute error, so collapses across a front of the attribute wait. Set before any block.
    void setAttributeWeight(double weight) { mAttrWeight2 = weight * weight; }

    // Largest estimated displacement of a collapse made so far (same estimate; without a bound, the
    // quadric part only).
    double maxErrorAccepted() const { return mMaxErrorAccepted; }
    // Whether some edge still there was refused by the error bound alone (its link condition allows
    // the collapse and a placement keeps every face valid): once the passes stop above their target,
    // whether the bound held the surface there rather than its topology.
    bool boundRefusesAnEdge();

    // Polled every few thousand queue pops during decimateTo(); returning true stops the run by
    // throwing Cancelled (errors.h), so Ctrl-C is honoured inside long passes too.
    void setInterrupter(std::function<bool()> stop) { mStop = std::move(stop); }

    // Faces of the surface, retired ones included; vertices still here, pinned ones included.
    size_t faceCount() const { return mFaceCount; }
    size_t vertexCount() const { return mVertexCount; }
    size_t uncontractibleFaces() const { return mUncontractibleFaces; }
    size_t openVertices() const { return mSealed ? mSealedOpen.size() : mOpen.size(); }
    // No more blocks come (a finished node of the merge tree): the open vertices move from the hash
    // map to an array sorted by key, 16 bytes a vertex against ~40, and merges weld by walking both
    // sorted lists. addBlock moves them back.
    void seal();
    uint64_t finalizations() const { return mFinalizations; }
    // Collapses tried by decimateTo(), legal or not: the work a pass did beyond queue upkeep.
    uint64_t collapseAttempts() const { return mWork.attempts; }
    // Everything decimateTo() did so far (counted since this decimator was made or copied from).
    const QueueWork& work() const { return mWork; }

    // The surviving mesh, compacted: the retired part first, then the vertices here in slot order.
    Mesh mesh() const;
    // The same mesh, made while the decimator lets go of its arrays: the queue and the rest first, then
    // each chunk of vertices and faces once copied, so the run's end holds the decimator or the mesh,
    // not both. The decimator is left empty but for parallelSeconds().
    Mesh takeMesh();

private:
    // Adjacency without per-vertex containers: every face corner (3 * face + k) is linked into a list
    // of the corners that share its vertex, headed at the vertex. No allocation per vertex or face,
    // and a vertex's faces are walked by following `next`.
    static constexpr uint32_t kNone = UINT32_MAX;
    // A vertex in two arrays: what the queue and the ring walks read on every step (16 bytes, four
    // to a cache line) apart from the geometry the cost and fold checks need (104 bytes).
    // One 88-byte record made every queue check load a line or two of position and quadric it did
    // not use.
    struct VertexGeom {
        std::array<double, 3> p{};
        // Written around p, where the planes of the vertex's own faces have no linear or constant
        // part, so precision does not depend on how far the mesh is from the origin. In double: a
        // float quadric of a large flat region (area 1e3, rank 1) carries rounding noise of 1e-4 in
        // its other directions, as large as the cost of cutting a sharp edge, and let collapses swing
        // triangles across edges as if they were free.
        Quadric q;
    };
    struct VertexMeta {
        VertexMeta() : ring(0), pinned(0), alive(0), final(0) {}
        uint32_t version = 0;  // bumped on every change, so stale queue entries can be recognised
        uint32_t head = kNone; // first corner of this vertex
        uint32_t mark = 0;     // scratch stamp for ring walks (dedupe without sorting)
        // Bumped whenever a face around the vertex changes (a collapse at it or at a neighbour): a
        // refused collapse can only become legal once this changes at one of its ends. Refusals keep
        // 30 bits of the sum of two; a vertex sees far fewer than 2^29 changes.
        uint32_t ring : 29;
        uint32_t pinned : 1;  // a corner of retired faces (retireInterior): its point is written
        uint32_t alive : 1;
        uint32_t final : 1;
    };
    static_assert(sizeof(VertexMeta) == 16, "vertex records stay 16 bytes");
    // 24 bytes: whether a face is uncontractible (a corner not final) is read off its corners' records
    // where it changes, not stored.
    struct Face {
        std::array<uint32_t, 3> v{};
        std::array<uint32_t, 3> next{};  // next corner of the same vertex, per corner
        bool alive() const { return v[0] != kNone; }  // killFace marks a dead face
    };
    static_assert(sizeof(Face) == 24, "face records stay 24 bytes");
    bool anyOpen(const Face& f) const { return !mMeta[f.v[0]].final || !mMeta[f.v[1]].final || !mMeta[f.v[2]].final; }
    // A queued edge, 16 bytes so four siblings of the queue's 4-ary heap part share a cache line.
    // `stamp` is the sum of both versions at push time: versions only grow, so an unchanged sum means
    // neither end changed.
    // The placement is recomputed when the entry is popped (the quadrics are the same then).
    struct Candidate {
        uint64_t key;  // cost (float bits) << 32 | lower end
        uint32_t b, stamp;
        uint32_t a() const { return uint32_t(key); }
        float cost() const
        {
            const uint32_t bits = costBits();
            float f;
            std::memcpy(&f, &bits, sizeof f);
            return f;
        }
        uint32_t costBits() const { return uint32_t(key >> 32); }
        static Candidate make(uint32_t costBits, uint32_t a, uint32_t b, uint32_t stamp)
        {
            return {uint64_t(costBits) << 32 | a, b, stamp};
        }
        // Queue order: cost, then the lower end, then the higher one, so the collapse sequence never
        // depends on heap internals. Cost and lower end share one 64-bit key (non-negative floats
        // order like their bits): the hottest comparison is one integer compare.
        bool operator<(const Candidate& o) const { return key != o.key ? key < o.key : b < o.b; }
    };

    uint32_t newVertex(const std::array<double, 3>& p);
    uint32_t newFace(const std::array<uint32_t, 3>& v);
    void killFace(uint32_t f);
    void killVertex(uint32_t v);
    void finalize(uint32_t v);
    uint32_t nextStamp();
    void neighbours(uint32_t v, std::vector<uint32_t>& out);
    // Starts loading vertex v's position and quadric (a cost evaluation is about to read them).
    void prefetchGeom(uint32_t v) const;
    // A candidate position of a collapse's survivor and the edge quadric's error there.
    struct Placement {
        std::array<double, 3> p;
        double cost;
        double geoCost;  // of which: the geometric quadric's part (the error bound's estimate reads it)
    };
    static constexpr size_t kPlacements = 5;
    // The candidates of edge ab, cheapest first; returns how many (at most kPlacements). With
    // cheapestOnly, out[0] is the cheapest (for the queue's cost) and may be the only one.
    size_t placements(uint32_t a, uint32_t b, Placement out[kPlacements], bool cheapestOnly) const;
    void push(uint32_t a, uint32_t b);
    void pushAt(uint32_t a, uint32_t b, double cost);
    bool current(const Candidate& c) const;
    bool edgeExists(uint32_t a, uint32_t b) const;
    bool liveFinalPair(uint32_t a, uint32_t b) const;
    void dropDeadEntries();
    // Collapses the edge of face f (with aroundFace: the other edges at its corners) whose cheapest
    // valid placement costs least; for zero-area faces.
    bool collapseCheapestEdge(uint32_t f, bool aroundFace);
    bool openPinch(uint32_t f);
    // Refused: the link condition (topology); Folds: no placement keeps every face valid.
    enum class Outcome { Collapsed, Refused, Folds, Costlier, TooFar };
    // sqrt(cost / weight) of edge ab at a placement of that cost (setMaxError).
    double displacement(uint32_t a, uint32_t b, double cost) const;
    // How far the surface around ab moves when ab collapses to p: the largest distance of the corners,
    // centroids and edge midpoints of the faces around a and b before from the faces after, and the
    // other way. Any result above `limit` may stop the search early.
    double fanDistance(uint32_t a, uint32_t b, const std::array<double, 3>& p, double limit) const;
    // What absorb reads of the other side of a merge, in a piece's numbering (alive vertices densely,
    // in id order), each part once and freed as it is read: a MeshPiece, or another decimator's own
    // arrays (decimator.cpp). takePiece is absorb's reading of a decimator written into a piece.
    class PieceSource;
    class DecimatorSource;
    template <typename Source>
    void absorbFrom(Source& from);
    // Slab merge: vertex `mine` takes over what the other side's vertex `theirs` carries beyond position
    // and quadric (a welded seam vertex sums them): the larger drift under a bound, the attribute quadric.
    template <typename Source>
    void copyExtras(uint32_t mine, const Source& from, uint32_t theirs);
    // Collapses ab when the topology allows it and a placement keeps every face valid, unless the
    // cheapest such placement costs more than maxCost: then *cost gets its cost (Costlier), or when it
    // moves the surface by more than the error bound (TooFar).
    Outcome collapse(uint32_t a, uint32_t b, float maxCost, double* cost);
    // What edgeMayCollapse learns of edge ab for mergeEnds.
    struct EdgeLink {
        uint32_t shared[2], opposite[2];  // the edge's two faces and their corners off the edge
        size_t valenceA = 0, valenceB = 0;
        uint32_t inA = 0, inB = 0;        // stamps of the neighbours each end brings
    };
    bool edgeMayCollapse(uint32_t a, uint32_t b, EdgeLink& e);
    void mergeEnds(uint32_t a, uint32_t b, const EdgeLink& e, const std::array<double, 3>& target);
    bool degenerate(uint32_t f) const;
    // The same test against another area (in the units of the positions, squared).
    bool degenerate(uint32_t f, double zeroArea) const;
    bool dropFlatComponent(uint32_t seedFace);
    // A connected component (faces sharing vertices, a pinned vertex shared with its retired point):
    // its area, first face (a live face's slot, or the slots' count plus a retired face's number), its
    // live faces and its retired ones.
    struct Component {
        double area = 0;
        uint64_t firstFace = UINT64_MAX;
        std::vector<uint32_t> faces;
        std::vector<uint32_t> retired;
    };
    // Every component of the surface, live and retired parts together, smallest area first (ties:
    // lowest first face), for the clean-ups that remove whole components (dropSmallComponents,
    // pruneComponents).
    std::vector<Component> componentsByArea() const;
    // A representative of each one's component: per vertex slot, then, `withRetired`, per retired
    // point (at the slots' count plus its number), joined to the live part by the pinned vertices.
    PooledVector<uint32_t> componentRoots(bool withRetired) const;
    // Removes c's live faces and vertices; its retired faces are counted out here and appended to
    // `retiredGone`, for dropRetired once every component is dropped.
    void dropComponent(const Component& c, std::vector<uint32_t>& retiredGone);
    // Rewrites the retired mesh without the faces `gone` names and the points only they used; a
    // pinned vertex follows its point, or dies with it.
    void dropRetired(const std::vector<uint32_t>& gone);
    bool facesStayValid(uint32_t moved, uint32_t other, const std::array<double, 3>& p) const;
    // What collapse() checks of ab before cost and bound: Refused when the link condition forbids it
    // (edgeMayCollapse fills `e`), Folds when none of its placements (filled in `places`, cheapest
    // first) keeps every face valid, else Collapsed: nothing here forbids it, and `*place` is the
    // cheapest valid placement.
    Outcome placeCollapse(uint32_t a, uint32_t b, EdgeLink& e, Placement places[kPlacements], size_t* place);
    // Appends this decimator's live mesh to `out`, which holds the retired part.
    template <typename VerticesRead, typename FacesRead>
    void collectMesh(Mesh& out, VerticesRead verticesRead, FacesRead facesRead) const;
    // A face of less area than this many voxel faces (or degenerate in shape) may become zero-area after
    // collapses around it: retireInterior keeps it live.
    static constexpr double kRetireMinArea = 1e-3;

    ChunkedVector<VertexGeom> mGeom;
    ChunkedVector<VertexGeom>::Spares mGeomSpares;  // during absorb(Decimator&&): the other side's read chunks
    ChunkedVector<VertexMeta> mMeta;
    ChunkedVector<Face> mFaces;
    PooledVector<uint32_t> mFreeVerts, mFreeFaces;
    std::unordered_map<EdgeKey, uint32_t> mOpen;  // frontier: vertices not final yet, by edge key
    std::vector<std::pair<EdgeKey, uint32_t>> mSealedOpen;  // the same once sealed (seal()), sorted
    bool mSealed = false;
    void unseal();
    RadixQueue<Candidate> mHeap;
    static constexpr size_t kCoolAboveEntries = 4096;  // smaller queues stay whole
    // Queues of more than mForgetAbove entries drop their entries above a bar (RadixQueue::forgetFrom)
    // and list every edge again when the queue runs out below the bar (requeueForgotten). Listing them
    // costs a cost evaluation an edge where keeping them costs none: a slab's queue, which runs out
    // below its bar at most passes, keeps them; near the top of the merge tree the bar is rarely
    // reached (no time at 448^3, docs/perf.md).
    size_t mForgetAbove = size_t(1) << 20;
    void requeueForgotten();
    // Refused collapses, retried in a later pass once the faces around an end have changed. `stamp` is
    // the sum of both ends' ring counters at refusal (its low 30 bits: the record stays 12 bytes, and
    // there can be hundreds of thousands at a merge), so a collapse that cannot succeed (a closed
    // tetrahedron in noisy data) is not tried again at every batch.
    struct Refused {
        uint32_t a, b;
        uint32_t stamp : 30;
        uint32_t why : 2;  // a Refusal: retryFolds retries the folds, boundRefusesAnEdge looks for the bound
    };
    static_assert(sizeof(Refused) == 12, "refused pairs stay 12 bytes");
    Refused refusal(uint32_t a, uint32_t b, Refusal why) const
    {
        return {a, b, (mMeta[a].ring + mMeta[b].ring) & 0x3fffffffu, uint32_t(why)};
    }
    bool ringsChanged(const Refused& r) const { return refusal(r.a, r.b, Refusal::Topology).stamp != r.stamp; }
    // In chunks of 12 KB: a merge appends its child's pairs and passes append more, and a doubling
    // std::vector would hold up to twice the pairs.
    ChunkedVector<Refused, 10> mRefused;
    // The refused pairs `retry` picks go back to the queue (those still an edge); the others of living
    // vertices stay refused.
    template <typename Retry>
    void retryRefused(Retry retry)
    {
        size_t kept = 0;
        for (const Refused& r : mRefused) {
            if (!mMeta[r.a].alive || !mMeta[r.b].alive) continue;
            if (!retry(r)) mRefused[kept++] = r;
            else if (edgeExists(r.a, r.b)) push(r.a, r.b);
        }
        mRefused.truncate(kept);
    }

    size_t mFaceCount = 0, mVertexCount = 0, mUncontractibleFaces = 0;
    uint64_t mFinalizations = 0;
    QueueWork mWork;
    double mMinNormalCos = kDefaultMinNormalCos;
    static constexpr double kMinPlaneWeight = 0.25;  // of a voxel face's area, per face
    static constexpr double kMinVertexWeight = 2.0;  // of a voxel face's area, per vertex
    double mMinPlaneWeight = kMinPlaneWeight;
    double mMinVertexWeight = kMinVertexWeight;
    double mMaxError = HUGE_VAL, mMaxErrorAccepted = 0.0;
    // Under a bound, per vertex: how far the surface around it may have moved from the full-resolution
    // one, the sum of the local displacements of the collapses that made it (empty without a bound).
    ChunkedVector<float> mDrift;
    double mAttrWeight2 = 0.0;
    ChunkedVector<AttributeQuadric> mAttrQ;  // per vertex, written around it; empty without a weight
    double mParallelSeconds = 0.0;
    double mZeroArea = 0.0;  // faces of at most this area count as degenerate (removeDegenerateFaces)
    std::vector<uint32_t>* mMoved = nullptr;  // removeDegenerateFaces: vertices whose faces a fix changed
    std::function<bool()> mStop;
    uint64_t mPolls = 0;
    uint32_t mStamp = 0;
    std::vector<uint32_t> mScratchA, mScratchB;
    std::vector<uint32_t> mSeam;  // the vertices the last finalizeOpen made final
    RetiredMesh mRetired;         // retireInterior
    std::unordered_map<uint32_t, uint32_t> mPinnedAt;  // pinned vertex -> its point in mRetired
    using Tri = std::array<std::array<double, 3>, 3>;
    struct FanFace {
        Tri t;
        uint8_t moving;  // bit k: corner k is an end of the edge (before) or the new vertex (after)
    };
    mutable std::vector<FanFace> mFanBefore, mFanAfter;  // fanDistance's faces, kept to spare allocations
};

} // namespace vdb_isosimp
