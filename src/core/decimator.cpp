#include "core/decimator.h"

#include "core/chunk_pool.h"
#include "core/stopwatch.h"
#include "vdb_isosimp/errors.h"

#include <algorithm>
#include <malloc.h>
#include <cmath>
#include <cstring>
#include <iterator>
#include <limits>
#include <numeric>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace vdb_isosimp {

namespace {

using V3 = std::array<double, 3>;
V3 sub(const V3& a, const V3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
V3 cross(const V3& a, const V3& b) { return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]}; }
double dot(const V3& a, const V3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Faces whose area is this small relative to their squared edge lengths count as degenerate: a collapse
// may not create one. (An equilateral triangle scores 0.29.)
constexpr double kMinShape = 1e-5;
// Below this, an existing face counts as degenerate (zero area, up to rounding) and is cleaned up.
constexpr double kDegenerateShape = 1e-10;
// Each face also anchors its corners: a point quadric of this fraction of its plane weight, so moving
// a vertex costs a little for the distance from where its merged vertices were. Among collapses that
// cost nothing on the planes (flat regions, straight edges, coincident twins where voxels sit at the
// iso-value) the shortest then go first and survivors settle at the centroid of what they absorbed,
// instead of exact ties broken by vertex index sweeping flat regions into fans across exactly planar
// data. Far below the plane terms: a vertex
// moved across a face keeps 1e-8 of the cost of moving it off the face's plane by the same distance.
constexpr double kAnchorWeight = 1e-8;

// Squared distance from p to triangle (a, b, c): Ericson, "Real-Time Collision Detection", 5.1.5.
double pointTriangleDistance2(const V3& p, const V3& a, const V3& b, const V3& c)
{
    const V3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
    const auto dist2 = [&](const V3& q) { const V3 d = sub(p, q); return dot(d, d); };
    const auto along = [](const V3& o, const V3& e, double t) { return V3{o[0] + t * e[0], o[1] + t * e[1], o[2] + t * e[2]}; };
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return dist2(a);
    const V3 bp = sub(p, b);
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return dist2(b);
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) return dist2(along(a, ab, d1 / (d1 - d3)));
    const V3 cp = sub(p, c);
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return dist2(c);
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) return dist2(along(a, ac, d2 / (d2 - d6)));
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return dist2(along(b, sub(c, b), (d4 - d3) / ((d4 - d3) + (d5 - d6))));
    const double denom = va + vb + vc;
    if (!(std::abs(denom) > 0)) return std::min({dist2(a), dist2(b), dist2(c)});  // no area: its corners
    const double v = vb / denom, w = vc / denom;
    return dist2({a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w});
}

// Area of triangle (a, b, c), its corners in double (live vertices) or float (retired points).
template <typename P>
double triangleArea(const P& a, const P& b, const P& c)
{
    const V3 n = cross(V3{double(b[0]) - a[0], double(b[1]) - a[1], double(b[2]) - a[2]},
                       V3{double(c[0]) - a[0], double(c[1]) - a[1], double(c[2]) - a[2]});
    return 0.5 * std::sqrt(dot(n, n));
}

} // namespace

uint32_t Decimator::newVertex(const std::array<double, 3>& p)
{
    uint32_t id;
    if (!mFreeVerts.empty()) {
        id = mFreeVerts.back();
        mFreeVerts.pop_back();
    } else {
        id = uint32_t(mMeta.size());
        mGeom.emplace_back(&mGeomSpares);
        mMeta.emplace_back();
    }
    mGeom[id] = {p, Quadric{}};
    if (mMaxError < HUGE_VAL) {
        if (id >= mDrift.size()) mDrift.emplace_back();
        mDrift[id] = 0.0f;
    }
    if (mAttrWeight2 > 0) {
        if (id >= mAttrQ.size()) mAttrQ.emplace_back();
        mAttrQ[id] = AttributeQuadric{};
    }
    VertexMeta& v = mMeta[id];
    ++v.version;  // a reused slot must not match stale queue entries (or refused ones)
    ++v.ring;
    v.alive = true;
    v.final = false;
    v.pinned = false;
    v.head = kNone;
    ++mVertexCount;
    return id;
}

uint32_t Decimator::newFace(const std::array<uint32_t, 3>& v)
{
    uint32_t id;
    if (!mFreeFaces.empty()) {
        id = mFreeFaces.back();
        mFreeFaces.pop_back();
    } else {
        id = uint32_t(mFaces.size());
        mFaces.emplace_back();
    }
    Face& f = mFaces[id];
    f.v = v;
    if (anyOpen(f)) ++mUncontractibleFaces;
    for (int k = 0; k < 3; ++k) {
        f.next[k] = mMeta[v[k]].head;
        mMeta[v[k]].head = 3 * id + uint32_t(k);
    }
    ++mFaceCount;
    return id;
}

void Decimator::killFace(uint32_t id)
{
    Face& f = mFaces[id];
    for (uint32_t k = 0; k < 3; ++k) {
        // Unlink corner 3*id+k from its vertex's list (short: the vertex's valence).
        const uint32_t corner = 3 * id + k;
        uint32_t* link = &mMeta[f.v[k]].head;
        while (*link != corner) link = &mFaces[*link / 3].next[*link % 3];
        *link = f.next[k];
    }
    if (anyOpen(f)) --mUncontractibleFaces;
    f.v[0] = kNone;
    mFreeFaces.push_back(id);
    --mFaceCount;
}

void Decimator::killVertex(uint32_t v)
{
    VertexMeta& x = mMeta[v];
    if (x.pinned) mPinnedAt.erase(v);
    x.alive = false;
    x.pinned = false;
    x.head = kNone;
    ++x.version;
    mFreeVerts.push_back(v);
    --mVertexCount;
}

uint32_t Decimator::nextStamp()
{
    if (mStamp >= UINT32_MAX - 4) {
        for (VertexMeta& v : mMeta) v.mark = 0;
        mStamp = 0;
    }
    return ++mStamp;
}

void Decimator::prefetchGeom(uint32_t v) const
{
    // A record spans up to three cache lines.
    const char* g = reinterpret_cast<const char*>(&mGeom[v]);
    __builtin_prefetch(g);
    __builtin_prefetch(g + 64);
    __builtin_prefetch(g + sizeof(VertexGeom) - 1);
}

void Decimator::neighbours(uint32_t v, std::vector<uint32_t>& out)
{
    // Each neighbour once, in ring-walk order; a stamp per vertex replaces sorting.
    out.clear();
    const uint32_t stamp = nextStamp();
    for (uint32_t c = mMeta[v].head; c != kNone; c = mFaces[c / 3].next[c % 3])
        for (uint32_t x : mFaces[c / 3].v)
            if (x != v && mMeta[x].mark != stamp) {
                mMeta[x].mark = stamp;
                out.push_back(x);
            }
}

// The quadric of edge ab written around a's position (both ends' quadrics summed there).
static Quadric edgeQuadric(const V3& pa, const Quadric& qa, const V3& pb, const Quadric& qb)
{
    Quadric q = qa;
    q += qb.shifted(sub(pa, pb));
    return q;
}

size_t Decimator::placements(uint32_t a, uint32_t b, Placement out[kPlacements], bool cheapestOnly) const
{
    const VertexGeom& va = mGeom[a];
    const VertexGeom& vb = mGeom[b];
    const Quadric q = edgeQuadric(va.p, va.q, vb.p, vb.q);
    // Positions relative to a: the quadric's optimum where it is well conditioned, the best point of
    // segment ab (where the optimum is not unique, along flat and straight regions, it picks the
    // point the edge itself prefers), the ends and the midpoint.
    const V3 d = sub(vb.p, va.p);
    size_t n = 0;
    V3 y;
    if (q.optimum(y)) {
        out[n++] = {y, 0, 0};
        // The optimum is the cheapest point there is (of the geometry: an attribute may prefer another).
        if (cheapestOnly && !(mAttrWeight2 > 0)) {
            out[0].cost = out[0].geoCost = std::max(0.0, q.error(y));
            return 1;
        }
    }
    const double dAd = q.q[0] * d[0] * d[0] + q.q[4] * d[1] * d[1] + q.q[7] * d[2] * d[2] +
                       2 * (q.q[1] * d[0] * d[1] + q.q[2] * d[0] * d[2] + q.q[5] * d[1] * d[2]);
    const double bd = q.q[3] * d[0] + q.q[6] * d[1] + q.q[8] * d[2];
    if (dAd > 0) {
        const double t = -bd / dAd;
        if (t > 0 && t < 1) out[n++] = {{t * d[0], t * d[1], t * d[2]}, 0, 0};
    }
    out[n++] = {{0, 0, 0}, 0, 0};
    out[n++] = {d, 0, 0};
    out[n++] = {{d[0] / 2, d[1] / 2, d[2] / 2}, 0, 0};
    for (size_t i = 0; i < n; ++i) out[i].cost = out[i].geoCost = std::max(0.0, q.error(out[i].p));
    if (mAttrWeight2 > 0) {
        AttributeQuadric attr = mAttrQ[a];
        attr += mAttrQ[b].shifted(sub(va.p, vb.p));
        for (size_t i = 0; i < n; ++i) out[i].cost += mAttrWeight2 * attr.error(out[i].p);
    }
    for (size_t i = 0; i < n; ++i) out[i].p = {va.p[0] + out[i].p[0], va.p[1] + out[i].p[1], va.p[2] + out[i].p[2]};
    // Cheapest first; ties keep the order above. Insertion sort: at most five entries, where
    // std::stable_sort would allocate a buffer on every call.
    for (size_t i = 1; i < n; ++i) {
        const Placement x = out[i];
        size_t j = i;
        for (; j > 0 && x.cost < out[j - 1].cost; --j) out[j] = out[j - 1];
        out[j] = x;
    }
    return n;
}

void Decimator::push(uint32_t a, uint32_t b)
{
    if (mMeta[a].pinned || mMeta[b].pinned) return;  // its point is in the retired mesh already
    // The cheapest placement, valid or not: a lower bound on what the collapse will cost (collapse()
    // checks validity and sends the pair back when a valid placement costs more).
    Placement p[kPlacements];
    placements(a, b, p, true);
    pushAt(a, b, p[0].cost);
}

void Decimator::pushAt(uint32_t a, uint32_t b, double cost)
{
    const float f = float(cost);
    uint32_t bits;
    std::memcpy(&bits, &f, sizeof bits);
    mHeap.push(Candidate::make(bits, a, b, mMeta[a].version + mMeta[b].version));
}

bool Decimator::edgeExists(uint32_t a, uint32_t b) const
{
    if (!mMeta[a].alive || !mMeta[b].alive || !mMeta[a].final || !mMeta[b].final) return false;
    for (uint32_t c = mMeta[a].head; c != kNone; c = mFaces[c / 3].next[c % 3]) {
        const auto& fv = mFaces[c / 3].v;
        if (fv[0] == b || fv[1] == b || fv[2] == b) return true;
    }
    return false;
}

bool Decimator::liveFinalPair(uint32_t a, uint32_t b) const
{
    const VertexMeta &x = mMeta[a], &y = mMeta[b];
    return x.alive && y.alive && x.final && y.final && !x.pinned && !y.pinned;
}

bool Decimator::current(const Candidate& c) const
{
    const VertexMeta& va = mMeta[c.a()];
    const VertexMeta& vb = mMeta[c.b];
    return va.alive && vb.alive && va.version + vb.version == c.stamp;
}

void Decimator::finalize(uint32_t v)
{
    VertexMeta& vx = mMeta[v];
    // Every face around v has arrived: a vertex whose faces have little area in all (a filament a
    // fraction of a voxel wide, made of tiny faces) gets its quadric scaled up to mMinVertexWeight, so
    // a thin feature is not free to remove. The scale keeps the faces' relative weights: where a big
    // flat face meets the small chamfer faces Marching Cubes cuts along a sharp edge, the flat face
    // still outweighs them. (A floor of 0.4 of a voxel face per face alone let the chamfer faces
    // outvote it: tetrahedron_rotated R = 0.05 RMS 0.00322 % against OpenMesh's 0.00281 %; plain
    // area alone left noise_fog's filaments free to remove.) The weight is the quadric's trace: the
    // planes' normals are unit vectors.
    Quadric& q = mGeom[v].q;
    const double weight = q.q[0] + q.q[4] + q.q[7];
    if (weight > 0 && weight < mMinVertexWeight)
        for (double& x : q.q) x *= mMinVertexWeight / weight;
    vx.final = true;
    ++mFinalizations;
    for (uint32_t c = vx.head; c != kNone; c = mFaces[c / 3].next[c % 3])
        if (!anyOpen(mFaces[c / 3])) --mUncontractibleFaces;  // v was its last open corner
    neighbours(v, mScratchA);
    for (uint32_t n : mScratchA)
        if (mMeta[n].final) prefetchGeom(n);
    for (uint32_t n : mScratchA)
        if (mMeta[n].final) push(std::min(v, n), std::max(v, n));
}

bool Decimator::collapseCheapestEdge(uint32_t f, bool aroundFace)
{
    // The face's own edges, or with aroundFace the other edges at its corners: where the link condition
    // refuses every edge of a zero-area face (twins on a voxel corner with a third common neighbour),
    // collapsing a neighbouring edge first changes what the link condition sees.
    const auto v = mFaces[f].v;
    std::vector<std::pair<uint32_t, uint32_t>> edges;
    if (!aroundFace) {
        for (int k = 0; k < 3; ++k) edges.push_back({std::min(v[k], v[(k + 1) % 3]), std::max(v[k], v[(k + 1) % 3])});
    } else {
        for (uint32_t x : v) {
            neighbours(x, mScratchB);
            for (uint32_t n : mScratchB)
                if (n != v[0] && n != v[1] && n != v[2]) edges.push_back({std::min(x, n), std::max(x, n)});
        }
    }
    double best = std::numeric_limits<double>::infinity();
    std::pair<uint32_t, uint32_t> pick{kNone, kNone};
    for (const auto& [a, b] : edges) {
        double cost;
        if (!liveFinalPair(a, b) || collapse(a, b, -1.0f, &cost) != Outcome::Costlier) continue;
        if (cost < best) {
            best = cost;
            pick = {a, b};
        }
    }
    if (pick.first == kNone) return false;
    return collapse(pick.first, pick.second, std::numeric_limits<float>::infinity(), nullptr) == Outcome::Collapsed;
}

void Decimator::seal()
{
    if (mSealed) return;
    mSealedOpen.assign(mOpen.begin(), mOpen.end());
    std::sort(mSealedOpen.begin(), mSealedOpen.end());
    mOpen = {};
    mSealed = true;
}

void Decimator::unseal()
{
    if (!mSealed) return;
    mOpen.reserve(mSealedOpen.size());
    mOpen.insert(mSealedOpen.begin(), mSealedOpen.end());
    mSealedOpen = {};
    mSealed = false;
}

void Decimator::addBlock(const BlockMesh& block)
{
    unseal();
    std::vector<uint32_t> ids(block.keys.size());
    // A vertex the block finalises is never looked up by key again (its key appears once in the block,
    // and no later block has a cell around it): one it finds leaves the frontier map at once, by the
    // lookup's own iterator, and one it creates never enters it: three vertices in four (noise 160^3:
    // 85k of 357k insertions remain), each an insertion, a node allocation and an erasure less.
    for (size_t i = 0; i < block.keys.size(); ++i) {
        auto it = mOpen.find(block.keys[i]);
        if (it != mOpen.end()) {
            ids[i] = it->second;
            if (block.finalAfterBlock[i]) mOpen.erase(it);
        } else {
            ids[i] = newVertex(block.positions[i]);
            if (!block.finalAfterBlock[i]) mOpen.emplace(block.keys[i], ids[i]);
        }
    }
    for (const auto& t : block.triangles) {
        const std::array<uint32_t, 3> v{ids[t[0]], ids[t[1]], ids[t[2]]};
        newFace(v);
        // The face's plane quadric, and its anchor, added to its three corners, weighted by the face's
        // area but never below mMinPlaneWeight (a quarter of a voxel face): large flat faces outweigh the
        // small faces Marching Cubes cuts where the surface bends (a chamfer along a sharp edge), yet a
        // chamfer still holds an axis-aligned edge in place (plain area cuts a box's edges at B = 1000).
        // A vertex whose faces are all tiny (a filament a fraction of a voxel wide) gets more weight
        // in finalize(), so a thin feature is not free to remove.
        // A face without area (coincident vertices at a voxel on the iso-value) has no plane: its
        // normal is rounding noise.
        const V3 &p0 = mGeom[v[0]].p, &p1 = mGeom[v[1]].p, &p2 = mGeom[v[2]].p;
        const V3 n = cross(sub(p1, p0), sub(p2, p0));
        const double len = std::sqrt(dot(n, n));
        const double edges = dot(sub(p1, p0), sub(p1, p0)) + dot(sub(p2, p1), sub(p2, p1)) + dot(sub(p0, p2), sub(p0, p2));
        if (len > kDegenerateShape * edges) {
            const V3 u{n[0] / len, n[1] / len, n[2] / len};
            const double d = -dot(u, p0);
            const double weight = std::max(0.5 * len, mMinPlaneWeight);
            for (uint32_t x : v) {
                // The plane around each corner (it passes through all three, up to rounding).
                mGeom[x].q.addPlane(u, d + dot(u, mGeom[x].p), weight);
                mGeom[x].q.addPoint(kAnchorWeight * weight);
            }
            if (mAttrWeight2 > 0 && !block.attribute.empty()) {
                // The attribute, linear over the face: its gradient in the face's plane from the corner
                // values (each corner's value times the edge opposite it, turned a quarter in the plane).
                const double a0 = block.attribute[t[0]], a1 = block.attribute[t[1]], a2 = block.attribute[t[2]];
                const V3 e0 = cross(u, sub(p2, p1)), e1 = cross(u, sub(p0, p2)), e2 = cross(u, sub(p1, p0));
                V3 grad;
                for (int k = 0; k < 3; ++k) grad[size_t(k)] = (a0 * e0[size_t(k)] + a1 * e1[size_t(k)] + a2 * e2[size_t(k)]) / len;
                const double values[3] = {a0, a1, a2};
                for (int k = 0; k < 3; ++k) mAttrQ[v[size_t(k)]].addFace(grad, values[k], weight);
            }
        }
    }
    for (size_t i = 0; i < block.keys.size(); ++i)
        if (block.finalAfterBlock[i]) finalize(ids[i]);
}

// A merge hands the other side's queue entries and faces over in runs of this many: a run's reads of
// the arrays indexed by vertex (new numbers, versions) are started together before any is used, so
// their cache misses overlap instead of following one another (docs/perf.md).
static constexpr size_t kRun = 64;

// Calls `ahead` on every element of a run of an array, then `f` on each, freeing the array's chunks
// as they are passed.
template <typename T, unsigned Shift, typename Ahead, typename F>
static void drainInRuns(ChunkedVector<T, Shift>& items, Ahead ahead, F f)
{
    const size_t n = items.size();
    for (size_t run = 0; run < n; run += kRun) {
        const size_t end = std::min(n, run + kRun);
        for (size_t i = run; i < end; ++i) ahead(items[i]);
        for (size_t i = run; i < end; ++i) {
            f(items[i]);
            items.releaseThrough(i);
        }
    }
}

// What absorb reads of the other side of a merge, in a piece's numbering (the alive vertices
// densely, in id order). Each part is read once, in absorb's order, and freed as it is read; `ahead`
// sees a run's entries (their ends in that numbering) before `f` is called on them.
class Decimator::PieceSource {
public:
    explicit PieceSource(MeshPiece& piece) : mPiece(piece) {}
    size_t vertexCount() const { return mPiece.vertices.size(); }
    std::vector<std::pair<EdgeKey, uint32_t>> takeOpen() { return std::move(mPiece.open); }
    RetiredMesh takeRetired() { return std::move(mPiece.retired); }
    std::vector<std::pair<uint32_t, uint32_t>> takePinned() { return std::move(mPiece.pinned); }
    const V3& position(uint32_t i) const { return mPiece.vertices[i].p; }
    const Quadric& quadric(uint32_t i) const { return mPiece.vertices[i].q; }
    bool final(uint32_t i) const { return mPiece.vertices[i].final; }
    const float* drift(uint32_t i) const { return i < mPiece.drift.size() ? &mPiece.drift[i] : nullptr; }
    const AttributeQuadric* attributes(uint32_t i) const
    {
        return i < mPiece.attributes.size() ? &mPiece.attributes[i] : nullptr;
    }
    void release(uint32_t i) { mPiece.vertices.releaseThrough(i); }
    size_t queued() const { return mPiece.queue.size(); }
    uint32_t forgetFromBits() const { return mPiece.forgetFromBits; }
    template <typename Ahead, typename F>
    void drainQueue(Ahead ahead, F f)
    {
        drainInRuns(
            mPiece.queue, [&](const MeshPiece::Queued& c) { ahead(c.a, c.b); },
            [&](const MeshPiece::Queued& c) { f(c.costBits, c.a, c.b, c.stale); });
        mPiece.queue = {};
    }
    template <typename F>
    void drainRefused(F f)
    {
        for (const auto& r : mPiece.refused) f(r.a, r.b, r.why);
        mPiece.refused = {};
    }
    template <typename Ahead, typename F>
    void drainFaces(Ahead ahead, F f)
    {
        drainInRuns(mPiece.faces, ahead, f);
        mPiece = MeshPiece{};
    }

private:
    MeshPiece& mPiece;
};

// The same parts read straight from another decimator's arrays (takePiece, and a merge in one
// process): the numbering and what is dropped (dead queue entries, refused pairs of dead vertices)
// decided here once. The decimator is left empty.
class Decimator::DecimatorSource {
public:
    // recycler: the decimator absorbing this one, which fills the geometry and queue chunks read
    // again as it grows; null: they are freed.
    explicit DecimatorSource(Decimator& d, Decimator* recycler = nullptr)
        : mDec(d), mGeomSpares(recycler ? &recycler->mGeomSpares : nullptr), mHeapInto(recycler ? &recycler->mHeap : nullptr),
          mDense(d.mMeta.size(), kNone), mQueueable(d.mMeta.size(), {kNone, 0})
    {
        mIds.reserve(d.mVertexCount);  // exactly: a doubling vector held up to twice the numbers, at a merge's peak
        for (uint32_t v = 0; v < d.mMeta.size(); ++v)
            if (d.mMeta[v].alive) {
                mDense[v] = uint32_t(mIds.size());
                mIds.push_back(v);
                if (d.mMeta[v].final && !d.mMeta[v].pinned) mQueueable[v] = {mDense[v], d.mMeta[v].version};
            }
    }
    ~DecimatorSource() { mDec = Decimator{}; }
    size_t vertexCount() const { return mIds.size(); }
    // Open vertices in key order (hash-map order is not part of the output contract).
    std::vector<std::pair<EdgeKey, uint32_t>> takeOpen()
    {
        mDec.seal();
        std::vector<std::pair<EdgeKey, uint32_t>> open = std::move(mDec.mSealedOpen);
        for (auto& o : open) o.second = mDense[o.second];
        return open;
    }
    RetiredMesh takeRetired() { return std::move(mDec.mRetired); }
    // In number order.
    std::vector<std::pair<uint32_t, uint32_t>> takePinned()
    {
        std::vector<std::pair<uint32_t, uint32_t>> pinned;
        pinned.reserve(mDec.mPinnedAt.size());
        for (const auto& [v, at] : mDec.mPinnedAt) pinned.emplace_back(mDense[v], at);
        std::sort(pinned.begin(), pinned.end());
        mDec.mPinnedAt = {};
        return pinned;
    }
    const V3& position(uint32_t i) const { return mDec.mGeom[mIds[i]].p; }
    const Quadric& quadric(uint32_t i) const { return mDec.mGeom[mIds[i]].q; }
    bool final(uint32_t i) const { return mDec.mMeta[mIds[i]].final; }
    const float* drift(uint32_t i) const { return mIds[i] < mDec.mDrift.size() ? &mDec.mDrift[mIds[i]] : nullptr; }
    const AttributeQuadric* attributes(uint32_t i) const
    {
        return mIds[i] < mDec.mAttrQ.size() ? &mDec.mAttrQ[mIds[i]] : nullptr;
    }
    // Vertex i and every slot before it are read for the last time (dead slots included).
    void release(uint32_t i)
    {
        for (; mReleased <= mIds[i]; ++mReleased) {
            mDec.mGeom.releaseThrough(mReleased, mGeomSpares);
            mDec.mMeta.releaseThrough(mReleased);
        }
    }
    // Entries of a pair that is no longer two live final vertices are dropped, as dropDeadEntries does.
    size_t queued() const
    {
        size_t n = 0;
        mDec.mHeap.visit([&](const Candidate& c) { n += keeps(c); });
        return n;
    }
    uint32_t forgetFromBits() const
    {
        Candidate bar;
        return mDec.mHeap.forgets() && mDec.mHeap.coldBar(bar) ? bar.costBits() : 0;
    }
    template <typename Ahead, typename F>
    void drainQueue(Ahead ahead, F f)
    {
        // The queue names vertices in no order (about four entries a vertex): its entries read their
        // ends' new numbers and versions from one array of 8 bytes a vertex, not from the vertex
        // records and the number map at random, and a run's reads start together.
        std::array<Candidate, kRun> run;
        size_t n = 0;
        const auto flush = [&] {
            for (size_t i = 0; i < n; ++i) {
                __builtin_prefetch(&mQueueable[run[i].a()]);
                __builtin_prefetch(&mQueueable[run[i].b]);
            }
            size_t kept = 0;
            for (size_t i = 0; i < n; ++i)
                if (keeps(run[i])) {
                    run[kept++] = run[i];
                    ahead(mQueueable[run[i].a()].dense, mQueueable[run[i].b].dense);
                }
            for (size_t i = 0; i < kept; ++i) {
                const Renumbered a = mQueueable[run[i].a()], b = mQueueable[run[i].b];
                f(run[i].costBits(), a.dense, b.dense, a.version + b.version != run[i].stamp);
            }
            n = 0;
        };
        mDec.mHeap.drain(
            [&](const Candidate& c) {
                run[n++] = c;
                if (n == kRun) flush();
            },
            mHeapInto);
        flush();
        mQueueable = {};
    }
    // Refused pairs whose ends live.
    size_t refusedCount() const
    {
        size_t n = 0;
        for (const Refused& r : mDec.mRefused) n += live(r);
        return n;
    }
    template <typename F>
    void drainRefused(F f)
    {
        for (const Refused& r : mDec.mRefused)
            if (live(r)) f(mDense[r.a], mDense[r.b], Refusal(r.why));
        mDec.mRefused = {};
    }
    template <typename Ahead, typename F>
    void drainFaces(Ahead ahead, F f)
    {
        const size_t n = mDec.mFaces.size();
        std::array<std::array<uint32_t, 3>, kRun> run;
        for (size_t first = 0; first < n; first += kRun) {
            const size_t end = std::min(n, first + kRun);
            for (size_t i = first; i < end; ++i)
                if (mDec.mFaces[i].alive())
                    for (uint32_t v : mDec.mFaces[i].v) __builtin_prefetch(&mDense[v]);
            size_t count = 0;
            for (size_t i = first; i < end; ++i) {
                const Face& face = mDec.mFaces[i];
                if (face.alive()) {
                    run[count] = {mDense[face.v[0]], mDense[face.v[1]], mDense[face.v[2]]};
                    ahead(run[count++]);
                }
                mDec.mFaces.releaseThrough(i);
            }
            for (size_t i = 0; i < count; ++i) f(run[i]);
        }
    }

private:
    struct Renumbered {
        uint32_t dense, version;  // dense: kNone for a vertex that is dead or not final
    };
    bool keeps(const Candidate& c) const { return mQueueable[c.a()].dense != kNone && mQueueable[c.b].dense != kNone; }
    bool live(const Refused& r) const { return mDense[r.a] != kNone && mDense[r.b] != kNone; }

    Decimator& mDec;
    ChunkedVector<VertexGeom>::Spares* mGeomSpares;
    RadixQueue<Candidate>* mHeapInto;
    PooledVector<uint32_t> mDense;  // per slot: the vertex's number here, kNone if dead
    PooledVector<uint32_t> mIds;    // per number: the slot
    PooledVector<Renumbered> mQueueable;
    uint32_t mReleased = 0;
};

MeshPiece Decimator::takePiece()
{
    MeshPiece piece;
    DecimatorSource from(*this);
    piece.forgetFromBits = from.forgetFromBits();
    // First what needs the vertices' state besides the vertices themselves: the queued edges (with
    // whether each is stale) and the refused pairs.
    from.drainQueue([](uint32_t, uint32_t) {}, [&](uint32_t costBits, uint32_t a, uint32_t b, bool stale) {
        piece.queue.emplace_back() = {costBits, a, b, stale};
    });
    piece.refused.reserve(from.refusedCount());  // exactly: a doubling vector held up to twice the pairs
    from.drainRefused([&](uint32_t a, uint32_t b, Refusal why) { piece.refused.push_back({a, b, why}); });
    piece.open = from.takeOpen();
    piece.retired = from.takeRetired();
    piece.pinned = from.takePinned();
    for (uint32_t i = 0; i < from.vertexCount(); ++i) {
        piece.vertices.emplace_back() = {from.position(i), from.quadric(i), from.final(i)};
        if (const float* d = from.drift(i)) piece.drift.emplace_back() = *d;
        if (const AttributeQuadric* q = from.attributes(i)) piece.attributes.emplace_back() = *q;
        from.release(i);
    }
    from.drainFaces([](const std::array<uint32_t, 3>&) {}, [&](const std::array<uint32_t, 3>& f) { piece.faces.emplace_back() = f; });
    return piece;
}

MeshPiece Decimator::park()
{
    Decimator settings;
    settings.mMinNormalCos = mMinNormalCos;
    settings.mMinPlaneWeight = mMinPlaneWeight;
    settings.mMinVertexWeight = mMinVertexWeight;
    settings.mMaxError = mMaxError;
    settings.mMaxErrorAccepted = mMaxErrorAccepted;
    settings.mForgetAbove = mForgetAbove;
    settings.mAttrWeight2 = mAttrWeight2;
    settings.mStop = mStop;
    settings.mWork = mWork;
    settings.mFinalizations = mFinalizations;
    // A piece's refused pairs come back as unchanged since their refusal: those whose faces changed
    // meanwhile (the next pass would retry them) go back to the queue now.
    retryRefused([&](const Refused& r) { return ringsChanged(r); });
    // The queue's cool bar (coolFrom) carries over to the piece's return: a later forgetting bar stops
    // there, as if the piece had never left.
    Candidate bar;
    const bool cooled = mHeap.coldBar(bar);
    MeshPiece piece = takePiece();
    *this = std::move(settings);
    if (cooled) mHeap.coolFrom(bar);
    return piece;
}

template <typename Source>
void Decimator::copyExtras(uint32_t mine, const Source& from, uint32_t theirs)
{
    if (mMaxError < HUGE_VAL)
        if (const float* d = from.drift(theirs)) mDrift[mine] = std::max(mDrift[mine], *d);
    if (mAttrWeight2 > 0)
        if (const AttributeQuadric* q = from.attributes(theirs))
            mAttrQ[mine] += q->shifted(sub(mGeom[mine].p, from.position(theirs)));
}

void Decimator::absorb(MeshPiece&& piece)
{
    PieceSource from(piece);
    absorbFrom(from);
}

void Decimator::absorb(Decimator&& other)
{
    // The other side's geometry and queue chunks, once read, become this side's new ones: at the top
    // of the merge tree fresh chunks' page faults took a fifth or more of a join (docs/perf.md).
    DecimatorSource from(other, this);
    absorbFrom(from);
    mGeomSpares.clear();
    mHeap.dropSpares();
}

template <typename Source>
void Decimator::absorbFrom(Source& from)
{
    const size_t n = from.vertexCount();
    PooledVector<uint32_t> remap(n, UINT32_MAX);
    // Both open lists in key order, walked together into the merged one.
    seal();
    const std::vector<std::pair<EdgeKey, uint32_t>> theirOpen = from.takeOpen();
    std::vector<std::pair<EdgeKey, uint32_t>> open;
    open.reserve(mSealedOpen.size() + theirOpen.size());
    auto mine = mSealedOpen.cbegin();
    for (const auto& [key, id] : theirOpen) {
        while (mine != mSealedOpen.cend() && mine->first < key) open.push_back(*mine++);
        if (mine != mSealedOpen.cend() && mine->first == key) {
            remap[id] = mine->second;
            VertexGeom& welded = mGeom[mine->second];
            welded.q = edgeQuadric(welded.p, welded.q, from.position(id), from.quadric(id));
            copyExtras(mine->second, from, id);
            open.push_back(*mine++);
        } else {
            remap[id] = newVertex(from.position(id));
            mGeom[remap[id]].q = from.quadric(id);
            copyExtras(remap[id], from, id);
            open.emplace_back(key, remap[id]);
        }
    }
    open.insert(open.end(), mine, mSealedOpen.cend());
    mSealedOpen = std::move(open);
    for (uint32_t v = 0; v < n; ++v) {
        if (remap[v] == UINT32_MAX) {
            remap[v] = newVertex(from.position(v));
            mGeom[remap[v]].q = from.quadric(v);
            copyExtras(remap[v], from, v);
            mMeta[remap[v]].final = from.final(v);
        }
        from.release(v);
    }
    // The other side's retired faces follow this side's; its pinned vertices point there.
    RetiredMesh retired = from.takeRetired();
    const uint32_t offset = uint32_t(mRetired.points.size());
    mFaceCount += retired.triangles.size();
    const auto nothingAhead = [](const auto&) {};
    drainInRuns(retired.points, nothingAhead, [&](const std::array<float, 3>& p) { mRetired.points.emplace_back() = p; });
    drainInRuns(retired.triangles, nothingAhead, [&](const std::array<uint32_t, 3>& t) {
        mRetired.triangles.emplace_back() = {t[0] + offset, t[1] + offset, t[2] + offset};
    });
    retired = {};
    for (const auto& [v, at] : from.takePinned()) {
        mMeta[remap[v]].pinned = true;
        mPinnedAt.emplace(remap[v], offset + at);
    }
    // Queued edges carry over with their costs (the quadrics of both ends are unchanged), so the final
    // pass needs no full requeue; welded seam vertices queue their edges when they are finalised.
    // Each piece vertex's number here and its version, side by side for the queue's random reads.
    PooledVector<std::pair<uint32_t, uint32_t>> renumbered(n);
    for (uint32_t v = 0; v < n; ++v) renumbered[v] = {remap[v], mMeta[remap[v]].version};
    // The other side's queue lacks its edges above its bar: this one drops its own from there too,
    // and lists them all again when it needs them.
    if (const uint32_t bits = from.forgetFromBits()) mHeap.forgetFrom(Candidate::make(bits, 0, 0, 0));
    const bool pushEach = mHeap.size() > from.queued();
    const auto renumberedAhead = [&](uint32_t ia, uint32_t ib) {
        __builtin_prefetch(&renumbered[ia]);
        __builtin_prefetch(&renumbered[ib]);
    };
    from.drainQueue(renumberedAhead, [&](uint32_t costBits, uint32_t ia, uint32_t ib, bool stale) {
        const auto [a, va] = renumbered[ia];
        const auto [b, vb] = renumbered[ib];
        // An entry that was stale stays stale (re-evaluated when popped).
        const uint32_t stamp = va + vb - (stale ? 1u : 0u);
        // Into a larger queue each entry is pushed (it sifts up a level or two on average); into a
        // smaller one they are appended and the whole is ordered once when next used.
        const Candidate e = Candidate::make(costBits, std::min(a, b), std::max(a, b), stamp);
        if (pushEach) mHeap.push(e);
        else mHeap.append(e);
    });
    renumbered = {};
    // Refused pairs come along as unchanged: both ends are final, so every face around them is
    // already in the piece and the merge adds none (it welds open vertices only). Retrying them at
    // every node of the merge tree tried each closed tetrahedron of a noisy surface once per level.
    from.drainRefused([&](uint32_t ra, uint32_t rb, Refusal why) {
        const uint32_t a = std::min(remap[ra], remap[rb]), b = std::max(remap[ra], remap[rb]);
        mRefused.emplace_back() = refusal(a, b, why);
    });
    const auto remapAhead = [&](const std::array<uint32_t, 3>& f) {
        for (uint32_t v : f) __builtin_prefetch(&remap[v]);
    };
    from.drainFaces(remapAhead, [&](const std::array<uint32_t, 3>& f) { newFace({remap[f[0]], remap[f[1]], remap[f[2]]}); });
}

size_t Decimator::finalizeRemaining()
{
    return finalizeOpen([](EdgeKey) { return true; });
}

size_t Decimator::finalizeOpen(const std::function<bool(EdgeKey)>& which)
{
    std::vector<uint32_t> open;
    if (mSealed) {
        size_t kept = 0;
        for (const auto& e : mSealedOpen)
            if (which(e.first)) open.push_back(e.second);
            else mSealedOpen[kept++] = e;
        mSealedOpen.resize(kept);
        mSealedOpen.shrink_to_fit();  // a node waiting for its sibling holds its seams only
    } else {
        for (auto it = mOpen.begin(); it != mOpen.end();) {
            if (which(it->first)) {
                open.push_back(it->second);
                it = mOpen.erase(it);
            } else {
                ++it;
            }
        }
    }
    std::sort(open.begin(), open.end());  // map order is not deterministic across runs
    for (uint32_t v : open) finalize(v);
    mSeam = std::move(open);
    return mSeam.size();
}

bool Decimator::facesStayValid(uint32_t moved, uint32_t other, const std::array<double, 3>& p) const
{
    for (uint32_t c = mMeta[moved].head; c != kNone; c = mFaces[c / 3].next[c % 3]) {
        const auto& fv = mFaces[c / 3].v;
        if (fv[0] == other || fv[1] == other || fv[2] == other) continue;  // removed by the collapse
        V3 q[3];
        for (int i = 0; i < 3; ++i) q[i] = fv[i] == moved ? p : mGeom[fv[i]].p;
        const V3 nNew = cross(sub(q[1], q[0]), sub(q[2], q[0]));
        const double edges = dot(sub(q[1], q[0]), sub(q[1], q[0])) + dot(sub(q[2], q[1]), sub(q[2], q[1])) +
                             dot(sub(q[0], q[2]), sub(q[0], q[2]));
        const double n2New = dot(nNew, nNew);
        const V3& a = mGeom[fv[0]].p;
        const V3 nOld = cross(sub(mGeom[fv[1]].p, a), sub(mGeom[fv[2]].p, a));
        // Most faces keep their shape and turn little: decided on squares, without the square roots,
        // where a relative margin of 1e-9 (far above their rounding) makes the answer the exact tests'.
        const double minNew = kMinShape * edges, turn = dot(nOld, nNew), n2Old = dot(nOld, nOld);
        if (n2New > minNew * minNew * (1 + 1e-9) && turn >= 0 &&
            (mMinNormalCos <= 0 || turn * turn > mMinNormalCos * mMinNormalCos * n2Old * n2New * (1 + 1e-9)))
            continue;
        const double lenNew = std::sqrt(n2New);
        const double lenOld = std::sqrt(n2Old);
        auto edgesOld = [&] {
            return dot(sub(mGeom[fv[1]].p, a), sub(mGeom[fv[1]].p, a)) +
                   dot(sub(mGeom[fv[2]].p, mGeom[fv[1]].p), sub(mGeom[fv[2]].p, mGeom[fv[1]].p)) +
                   dot(sub(a, mGeom[fv[2]].p), sub(a, mGeom[fv[2]].p));
        };
        if (!(lenNew > kMinShape * edges)) {
            // A face that was already degenerate (values exactly at the iso-value make coincident
            // vertices) may stay so: refusing would pin it forever instead of letting it be collapsed.
            if (lenOld > kMinShape * edgesOld()) return false;
            continue;
        }
        // A face without area has no orientation to keep: the normal of vertices a rounding error apart
        // points anywhere, and comparing with it would refuse, at random, the moves that open a
        // zero-width neck (coincident vertices around a voxel at the iso-value on a small handle).
        if (turn < mMinNormalCos * lenOld * lenNew && lenOld > kDegenerateShape * edgesOld()) return false;
    }
    return true;
}

// The two faces on edge ab and their opposite corners, and the link condition. Leaves both ends'
// rings in mScratchA, each neighbour stamped with the end(s) it belongs to.
bool Decimator::edgeMayCollapse(uint32_t a, uint32_t b, EdgeLink& e)
{
    // One walk around a finds the two faces on edge ab and their opposite corners, counts a's valence
    // and stamps a's ring. Link condition: the only common neighbours of a and b are the two opposite
    // corners; the walk around b checks it with the stamps. mScratchA gets the union of both rings
    // (what needs requeueing).
    uint32_t* shared = e.shared;
    uint32_t* opposite = e.opposite;
    int ns = 0;
    size_t& valenceA = e.valenceA;
    size_t& valenceB = e.valenceB;
    const uint32_t inA = nextStamp(), inBoth = nextStamp(), inB = nextStamp();
    e.inA = inA;
    e.inB = inB;
    std::vector<uint32_t>& ring = mScratchA;
    ring.clear();
    for (uint32_t c = mMeta[a].head; c != kNone; c = mFaces[c / 3].next[c % 3], ++valenceA) {
        const auto& fv = mFaces[c / 3].v;
        for (uint32_t x : fv)
            if (x != a && mMeta[x].mark != inA) {
                mMeta[x].mark = inA;
                ring.push_back(x);
            }
        if (fv[0] != b && fv[1] != b && fv[2] != b) continue;
        if (ns == 2) return false;  // non-manifold edge
        shared[ns] = c / 3;
        opposite[ns++] = fv[0] != a && fv[0] != b ? fv[0] : (fv[1] != a && fv[1] != b ? fv[1] : fv[2]);
    }
    if (ns != 2 || opposite[0] == opposite[1]) return false;
    size_t common = 0;
    for (uint32_t c = mMeta[b].head; c != kNone; c = mFaces[c / 3].next[c % 3], ++valenceB)
        for (uint32_t x : mFaces[c / 3].v) {
            if (x == b) continue;
            uint32_t& m = mMeta[x].mark;
            if (m == inA) {
                m = inBoth;
                ++common;
            } else if (m != inBoth && m != inB) {
                m = inB;
                ring.push_back(x);
            }
        }
    if (common != 2) return false;
    // A face on both sides of the common pair (a tetrahedron-like pocket) would be doubled.
    auto hasFaceWith = [&](uint32_t v) {
        for (uint32_t c = mMeta[v].head; c != kNone; c = mFaces[c / 3].next[c % 3]) {
            const auto& fv = mFaces[c / 3].v;
            const bool c0 = fv[0] == opposite[0] || fv[1] == opposite[0] || fv[2] == opposite[0];
            const bool c1 = fv[0] == opposite[1] || fv[1] == opposite[1] || fv[2] == opposite[1];
            if (c0 && c1) return true;
        }
        return false;
    };
    if (hasFaceWith(a) && hasFaceWith(b)) return false;
    return true;
}

// Moves `keep`'s end of ab to `target` and hands it the other end's faces (edgeMayCollapse's rings).
void Decimator::mergeEnds(uint32_t a, uint32_t b, const EdgeLink& e, const V3& target)
{
    // Keep the end with more faces (a shorter list to relink); the other one dies.
    const uint32_t keep = e.valenceA >= e.valenceB ? a : b;
    const uint32_t gone = keep == a ? b : a;
    killFace(e.shared[0]);
    killFace(e.shared[1]);
    VertexMeta& vk = mMeta[keep];
    const VertexMeta& vg = mMeta[gone];
    // Hand gone's corners to keep: rename, then splice gone's list in front of keep's.
    uint32_t last = kNone;
    for (uint32_t c = vg.head; c != kNone; c = mFaces[c / 3].next[c % 3]) {
        mFaces[c / 3].v[c % 3] = keep;
        last = c;
    }
    if (last != kNone) {
        mFaces[last / 3].next[last % 3] = vk.head;
        vk.head = vg.head;
    }
    VertexGeom& gk = mGeom[keep];
    const VertexGeom& gg = mGeom[gone];
    gk.q = edgeQuadric(gk.p, gk.q, gg.p, gg.q).shifted(sub(target, gk.p));
    if (mAttrWeight2 > 0) {
        AttributeQuadric& ak = mAttrQ[keep];
        ak += mAttrQ[gone].shifted(sub(gk.p, gg.p));
        ak = ak.shifted(sub(target, gk.p));
    }
    gk.p = target;
    if (mMoved) mMoved->push_back(keep);
    ++vk.version;
    ++vk.ring;
    const std::vector<uint32_t>& ring = mScratchA;
    for (uint32_t n : ring) ++mMeta[n].ring;
    killVertex(gone);
    // Queue the survivor's new edges (those the dead end brought). Its old edges keep their entries:
    // their costs are now lower bounds (quadrics only grow), so they are re-evaluated when popped.
    const uint32_t brought = gone == a ? e.inA : e.inB;
    const auto isNew = [&](uint32_t n) { return mMeta[n].mark == brought && n != keep && n != gone && mMeta[n].final; };
    for (uint32_t n : ring)
        if (isNew(n)) prefetchGeom(n);
    for (uint32_t n : ring)
        if (isNew(n)) push(std::min(keep, n), std::max(keep, n));
}

double Decimator::displacement(uint32_t a, uint32_t b, double cost) const
{
    // The trace of the 3x3 part is the sum of the plane weights (unit normals), and shifting a quadric
    // leaves it unchanged, so the edge quadric's weight is the sum of its ends'.
    const Quadric &qa = mGeom[a].q, &qb = mGeom[b].q;
    const double weight = qa.q[0] + qa.q[4] + qa.q[7] + qb.q[0] + qb.q[4] + qb.q[7];
    return weight > 0 ? std::sqrt(std::max(0.0, cost) / weight) : 0.0;
}

double Decimator::fanDistance(uint32_t a, uint32_t b, const V3& p, double limit) const
{
    // The faces around a and b before the collapse and after it (p in place of either end; the two
    // faces on ab vanish). Both ways, each side's moving corners, centroids and the midpoints of its
    // edges at a moving corner against the other side: a collapse that flattens a bump or a dent keeps
    // its corners on the surface but moves the middle of its faces. (The other corners and the edges
    // between them are on both sides.)
    std::vector<FanFace>& before = mFanBefore;
    std::vector<FanFace>& after = mFanAfter;
    before.clear();
    after.clear();
    for (const uint32_t end : {a, b})
        for (uint32_t c = mMeta[end].head; c != kNone; c = mFaces[c / 3].next[c % 3]) {
            const auto& fv = mFaces[c / 3].v;
            const bool hasA = fv[0] == a || fv[1] == a || fv[2] == a, hasB = fv[0] == b || fv[1] == b || fv[2] == b;
            if (end == b && hasA) continue;  // seen from a already
            FanFace old{{mGeom[fv[0]].p, mGeom[fv[1]].p, mGeom[fv[2]].p}, 0};
            for (int k = 0; k < 3; ++k) old.moving |= uint8_t((fv[k] == a || fv[k] == b) << k);
            before.push_back(old);
            if (hasA && hasB) continue;
            FanFace now = old;
            for (int k = 0; k < 3; ++k)
                if (old.moving >> k & 1) now.t[k] = p;
            after.push_back(now);
        }
    // Squared; stops early once the distance passes `limit` (the collapse is refused then anyway),
    // and a sample stops looking once a face is nearer than the worst so far, trying first the face
    // that corresponds to its own (the lists run in the same order).
    const double limit2 = limit * limit;
    const auto farthest = [limit2](const std::vector<FanFace>& from, const std::vector<FanFace>& to, double worst) {
        const auto mid = [](const V3& x, const V3& y) { return V3{(x[0] + y[0]) / 2, (x[1] + y[1]) / 2, (x[2] + y[2]) / 2}; };
        for (size_t i = 0; i < from.size(); ++i) {
            const Tri& t = from[i].t;
            V3 samples[6];
            int n = 0;
            samples[n++] = {(t[0][0] + t[1][0] + t[2][0]) / 3, (t[0][1] + t[1][1] + t[2][1]) / 3, (t[0][2] + t[1][2] + t[2][2]) / 3};
            for (int k = 0; k < 3; ++k) {
                const bool moving = from[i].moving >> k & 1, nextMoving = from[i].moving >> ((k + 1) % 3) & 1;
                if (moving) samples[n++] = t[k];
                if (moving || nextMoving) samples[n++] = mid(t[k], t[(k + 1) % 3]);
            }
            const size_t start = std::min(i, to.size() - 1);
            for (int s = 0; s < n; ++s) {
                double nearest = HUGE_VAL;
                for (size_t j = 0; j < to.size(); ++j) {
                    const Tri& u = to[(start + j) % to.size()].t;
                    nearest = std::min(nearest, pointTriangleDistance2(samples[s], u[0], u[1], u[2]));
                    if (nearest <= worst) break;
                }
                worst = std::max(worst, nearest);
                if (worst > limit2) return worst;
            }
        }
        return worst;
    };
    if (after.empty()) return HUGE_VAL;  // nothing would be left of the fan
    return std::sqrt(farthest(after, before, farthest(before, after, 0.0)));
}

Decimator::Outcome Decimator::collapse(uint32_t a, uint32_t b, float maxCost, double* cost)
{
    EdgeLink e;
    Placement places[kPlacements];
    size_t place = 0;
    const Outcome allowed = placeCollapse(a, b, e, places, &place);
    if (allowed != Outcome::Collapsed) return allowed;
    // The cheapest placement that keeps every face valid. Its cost, not the bound the pair was queued
    // with, decides: a fallback far costlier than the optimum goes back to the queue at its own cost
    // (collapsing it now let triangles swing across sharp edges at the price of a flat collapse).
    if (cost) *cost = places[place].cost;
    if (float(places[place].cost) > maxCost) return Outcome::Costlier;
    double moved = displacement(a, b, places[place].geoCost);
    // Under a bound, the quadric's plane distances are checked against the surface itself too: how
    // far the collapse moves the surface locally (fanDistance: a thin spike folded into its base costs
    // little on its nearly parallel side planes, yet moves its tip by its whole length), added to how
    // far the surface at either end had already drifted from the full-resolution one.
    double drift = 0.0;
    if (mMaxError < HUGE_VAL && moved <= mMaxError) {
        const double before = std::max(mDrift[a], mDrift[b]);
        drift = before + fanDistance(a, b, places[place].p, mMaxError - before);
        moved = std::max(moved, drift);
    }
    if (moved > mMaxError) return Outcome::TooFar;
    mMaxErrorAccepted = std::max(mMaxErrorAccepted, moved);
    if (mMaxError < HUGE_VAL) mDrift[a] = mDrift[b] = float(drift);  // the survivor keeps it

    mergeEnds(a, b, e, places[place].p);
    return Outcome::Collapsed;
}

size_t Decimator::decimateTo(size_t targetFaces)
{
    size_t collapses = 0;
    // Edges refused earlier (link condition, fold-overs) get another chance once the faces around an
    // end have changed; the others stay refused without a queue round trip.
    retryRefused([&](const Refused& r) { return ringsChanged(r); });
    while (mFaceCount > targetFaces) {
        if (mHeap.empty()) {
            if (!mHeap.forgets()) break;
            requeueForgotten();
            continue;
        }
        if (mStop && (++mPolls & 4095) == 0 && mStop()) throw Cancelled("cancelled");
        const Candidate c = mHeap.pop();
        ++mWork.pops;
        const uint32_t a = c.a(), b = c.b;
        // The next top is most often the next entry popped: its ends' records, read first to tell a
        // live entry from a stale or dead one, load while this one is dealt with.
        if (!mHeap.empty()) {
            const Candidate& next = mHeap.top();
            __builtin_prefetch(&mMeta[next.a()]);
            __builtin_prefetch(&mMeta[next.b]);
            // And their positions and quadrics, which a collapse attempt or a stale entry's new cost
            // reads first.
            prefetchGeom(next.a());
            prefetchGeom(next.b);
        }
        if (!current(c)) {
            // An end changed since the entry was queued: requeue at today's cost (it comes straight
            // back if it is still the cheapest). No ring walk to check the pair is still an edge: an
            // edge between two living vertices never disappears (a collapse renames the dead end's
            // edges, it removes none of the survivor's), so it is one unless a dead end's slot went to
            // a new vertex meanwhile (rare). collapse() finds no shared face
            // for such a pair and refuses it, so they cost one attempt and change no collapse.
            if (liveFinalPair(a, b)) {
                push(a, b);
                ++mWork.stale;
            } else {
                ++mWork.dead;
            }
            continue;
        }
        ++mWork.attempts;
        // The queued cost bounds every placement's from below (of the geometry; an attribute's part
        // would not): past the error bound already, the pair waits without the topology checks.
        if (mMaxError < HUGE_VAL && !(mAttrWeight2 > 0) && displacement(a, b, c.cost()) > mMaxError) {
            mRefused.emplace_back() = refusal(a, b, Refusal::Bound);
            continue;
        }
        double cost;
        const Outcome outcome = collapse(a, b, c.cost(), &cost);
        switch (outcome) {
        case Outcome::Collapsed:
            ++collapses;
            ++mWork.collapses;
            break;
        case Outcome::Refused: mRefused.emplace_back() = refusal(a, b, Refusal::Topology); break;
        case Outcome::Folds: mRefused.emplace_back() = refusal(a, b, Refusal::Folds); break;
        case Outcome::TooFar: mRefused.emplace_back() = refusal(a, b, Refusal::Bound); break;
        case Outcome::Costlier: pushAt(a, b, cost); break;
        }
    }
    // Entries of dead vertices pile up; drop them when they dominate the queue.
    if (mHeap.size() > 2 * mFaceCount + 1024) dropDeadEntries();
    // The next pass goes on from about this pass's last cost: a queue of more than mForgetAbove entries
    // drops those from the next power of two above it (1-2 times it) and lists them again if a pass
    // gets there (RadixQueue::forgetFrom); a smaller one keeps them and notes the bar (coolFrom), which a
    // later forgetting bar does not rise above while entries below it are left.
    // Non-negative float costs order like their bits: the bar is the next exponent, mantissa zero.
    if (mHeap.size() > kCoolAboveEntries) {
        const uint32_t exponent = mHeap.top().costBits() >> 23;
        if (exponent + 1 < 255) {
            const Candidate bar = Candidate::make((exponent + 1) << 23, 0, 0, 0);
            if (mHeap.size() > mForgetAbove) mHeap.forgetFrom(bar);
            else mHeap.coolFrom(bar);
        }
    }
    return collapses;
}

size_t Decimator::decimateRegionByRegion(size_t targetFaces, size_t regions)
{
    if (regions <= 1 || mFaceCount <= targetFaces || mVertexCount == 0) return decimateTo(targetFaces);
    if (mHeap.forgets()) requeueForgotten();  // the regions share out every entry
    std::array<double, 3> lo{HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (uint32_t v = 0; v < mMeta.size(); ++v)
        if (mMeta[v].alive)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], mGeom[v].p[k]);
                hi[k] = std::max(hi[k], mGeom[v].p[k]);
            }
    int axis = 0;
    for (int k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    // Region boundaries at quantiles of the vertices, not of the extent: each region then removes a
    // share in proportion to its faces (a region of equal width but sparse surface would lose its detail).
    // The temporaries are pool slots: a LOD chain splits every slab's copy like this, and arrays from
    // the heap were mapped and faulted in afresh each time (docs/perf.md).
    PooledVector<double> along;
    along.reserve(mVertexCount);
    for (uint32_t v = 0; v < mMeta.size(); ++v)
        if (mMeta[v].alive) along.push_back(mGeom[v].p[axis]);
    std::sort(along.begin(), along.end());
    std::vector<double> bounds;
    for (size_t r = 1; r < regions; ++r) bounds.push_back(along[along.size() * r / regions]);
    along = {};
    // Each live vertex's region, looked up once: the queue's entries then read this table, not the
    // positions of their ends.
    PooledVector<uint32_t> regionOf(mMeta.size());
    for (uint32_t v = 0; v < mMeta.size(); ++v)
        if (mMeta[v].alive)
            regionOf[v] = uint32_t(std::upper_bound(bounds.begin(), bounds.end(), mGeom[v].p[axis]) - bounds.begin());
    const auto regionOfPair = [&](const Candidate& c) { return std::max(regionOf[c.a()], regionOf[c.b]); };
    // The entries ordered by region, each region's in queue order (a counting sort): region r's are
    // waiting[first[r], first[r + 1]).
    PooledVector<size_t> first(regions + 1);
    mHeap.visit([&](const Candidate& c) {
        if (liveFinalPair(c.a(), c.b)) ++first[regionOfPair(c) + 1];
    });
    for (size_t r = 0; r < regions; ++r) first[r + 1] += first[r];
    PooledVector<Candidate> waiting(first[regions]);
    PooledVector<size_t> fill(first.begin(), first.end() - 1);
    mHeap.drain([&](const Candidate& c) {
        if (liveFinalPair(c.a(), c.b)) waiting[fill[regionOfPair(c)]++] = c;
    });
    regionOf = {};
    const size_t start = mFaceCount, remove = start - targetFaces;
    size_t collapses = 0;
    for (size_t r = 0; r < regions; ++r) {
        for (size_t i = first[r]; i < first[r + 1]; ++i) mHeap.append(waiting[i]);
        collapses += decimateTo(start - remove * (r + 1) / regions);
    }
    return collapses;
}

bool Decimator::degenerate(uint32_t f) const
{
    return degenerate(f, mZeroArea);
}

bool Decimator::degenerate(uint32_t f, double zeroArea) const
{
    // Far flatter than the slivers collapses may not create (kMinShape): a face of a sphere squeezed
    // to 1e-6 of its width on two axes scores about 1e-6 and is no defect, only a thin shape.
    const auto& v = mFaces[f].v;
    const V3 &p0 = mGeom[v[0]].p, &p1 = mGeom[v[1]].p, &p2 = mGeom[v[2]].p;
    const V3 n = cross(sub(p1, p0), sub(p2, p0));
    const double edges = dot(sub(p1, p0), sub(p1, p0)) + dot(sub(p2, p1), sub(p2, p1)) + dot(sub(p0, p2), sub(p0, p2));
    if (!(std::sqrt(dot(n, n)) > kDegenerateShape * edges)) return true;
    // The output is float: a tiny face can still collapse to zero area when rounded.
    auto rounded = [](const V3& p) { return V3{double(float(p[0])), double(float(p[1])), double(float(p[2]))}; };
    const V3 q0 = rounded(p0), q1 = rounded(p1), q2 = rounded(p2);
    const V3 m = cross(sub(q1, q0), sub(q2, q0));
    return 0.25 * dot(m, m) <= zeroArea * zeroArea;
}

bool Decimator::dropFlatComponent(uint32_t seed)
{
    // Only tiny closed components (a tetrahedron of vertices a hair apart, where one voxel sits at
    // the iso-value) can be all flat and beyond any legal collapse; look no further than 16 faces.
    std::vector<uint32_t> faces{seed}, verts;
    for (size_t i = 0; i < faces.size(); ++i) {
        if (!degenerate(faces[i])) return false;
        for (uint32_t v : mFaces[faces[i]].v) {
            if (mMeta[v].pinned) return false;  // part of a retired component
            if (std::find(verts.begin(), verts.end(), v) == verts.end()) verts.push_back(v);
            for (uint32_t c = mMeta[v].head; c != kNone; c = mFaces[c / 3].next[c % 3])
                if (const uint32_t g = c / 3; std::find(faces.begin(), faces.end(), g) == faces.end()) {
                    if (faces.size() == 16) return false;
                    faces.push_back(g);
                }
        }
    }
    for (uint32_t f : faces) killFace(f);
    for (uint32_t v : verts) killVertex(v);
    return true;
}

bool Decimator::openPinch(uint32_t f)
{
    // Where the surface touches itself at one voxel corner (values exactly at the iso-value on both
    // sides of it), no collapse keeps the mesh manifold: the link condition refuses every edge near the
    // twins. One corner moves off the other by 1e-5 of the diagonal, along the normal of its own faces
    // or else along an axis, which opens the pinch and gives the face an area without moving the
    // surface visibly (under an error bound the corner's drift counts the step).
    const double step = 1e-5 * std::sqrt(mZeroArea / 1e-12);
    for (int k = 0; k < 3; ++k) {
        const uint32_t x = mFaces[f].v[k];
        if (mMeta[x].pinned) continue;
        V3 normal{0, 0, 0};
        for (uint32_t c = mMeta[x].head; c != kNone; c = mFaces[c / 3].next[c % 3]) {
            const auto& fv = mFaces[c / 3].v;
            const V3 n = cross(sub(mGeom[fv[1]].p, mGeom[fv[0]].p), sub(mGeom[fv[2]].p, mGeom[fv[0]].p));
            for (int i = 0; i < 3; ++i) normal[i] += n[i];
        }
        const double len = std::sqrt(dot(normal, normal));
        // The normal first; where the corner's faces lie on both sheets of the pinch, moving along
        // their summed normal can fold one of them, and a move along an axis may not.
        const V3 directions[4] = {len > 0 ? V3{normal[0] / len, normal[1] / len, normal[2] / len} : V3{0, 0, 0},
                                  {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        for (int i = len > 0 ? 0 : 1; i < 4; ++i) {
            for (double sign : {1.0, -1.0}) {
                const V3& d = directions[i];
                const V3 old = mGeom[x].p;
                const V3 p{old[0] + sign * step * d[0], old[1] + sign * step * d[1], old[2] + sign * step * d[2]};
                if (!facesStayValid(x, kNone, p)) continue;
                mGeom[x].p = p;
                if (degenerate(f)) {
                    mGeom[x].p = old;
                    continue;
                }
                mGeom[x].q = mGeom[x].q.shifted(sub(p, old));
                if (mAttrWeight2 > 0) mAttrQ[x] = mAttrQ[x].shifted(sub(p, old));
                if (mMaxError < HUGE_VAL) mDrift[x] += float(step);
                ++mMeta[x].version;
                ++mMeta[x].ring;
                if (mMoved) mMoved->push_back(x);
                return true;
            }
        }
    }
    return false;
}

size_t Decimator::removeDegenerateFaces()
{
    // A zero-area face has no normal worth keeping, but its neighbours do: any turn short of a fold
    // is allowed. (Letting faces fold here turned a needle-thin sphere, 1e-6 voxels on two axes and
    // all slivers, inside out.) An error bound holds here too, as long as some fix keeps it: a
    // collapse that removes a face without area moves the faces around it by up to the face's
    // length, and around voxels at the iso-value that is a voxel or more.
    const double savedCos = mMinNormalCos;
    mMinNormalCos = 0.0;
    // Zero area also means tiny next to the whole surface: 1e-12 of the squared bounding-box diagonal
    // (vertices a hair apart around one voxel corner make such faces with a fair shape).
    V3 lo{HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    for (uint32_t v = 0; v < mMeta.size(); ++v)
        if (mMeta[v].alive)
            for (int k = 0; k < 3; ++k) {
                lo[k] = std::min(lo[k], mGeom[v].p[k]);
                hi[k] = std::max(hi[k], mGeom[v].p[k]);
            }
    for (size_t i = 0; i < mRetired.points.size(); ++i)  // the surface's box: the retired part is in it
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(mRetired.points[i][k]));
            hi[k] = std::max(hi[k], double(mRetired.points[i][k]));
        }
    const V3 diagonal = sub(hi, lo);
    mZeroArea = mVertexCount ? 1e-12 * dot(diagonal, diagonal) : 0.0;
    // Faces are found by a parallel scan and visited in face order, as a serial scan would. Collapses
    // here cannot make a face degenerate in double (facesStayValid), only, rarely, after rounding to
    // float: so the finds are looked at again until a round over them changes nothing. A face can
    // change only at a vertex a fix moved or handed faces to (mMoved), so the next round's finds are
    // the faces there and this round's that are still degenerate: the faces a full scan would find.
    // A face's corners lie anywhere in the vertex array of a merged mesh: the corner records of the
    // face kScanAhead places on start loading while this one is checked (docs/perf.md).
    constexpr uint32_t kScanAhead = 16;
    PooledVector<uint8_t> flat(mFaces.size(), 0);
    const Stopwatch scan;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(mFaces.size()), 4096), [&](const tbb::blocked_range<uint32_t>& r) {
        for (uint32_t f = r.begin(); f != r.end(); ++f) {
            if (r.end() - f > kScanAhead && mFaces[f + kScanAhead].alive())
                for (uint32_t v : mFaces[f + kScanAhead].v) __builtin_prefetch(&mGeom[v].p);
            flat[f] = mFaces[f].alive() && degenerate(f);
        }
    });
    mParallelSeconds += scan.seconds();
    std::vector<uint32_t> candidates;
    for (uint32_t f = 0; f < flat.size(); ++f)
        if (flat[f]) candidates.push_back(f);
    flat = {};
    std::vector<uint32_t> moved;
    mMoved = &moved;
    struct Unwatch {
        std::vector<uint32_t>*& watch;
        ~Unwatch() { watch = nullptr; }
    } unwatch{mMoved};
    size_t remaining = 0;
    const auto settle = [&] {
        while (!candidates.empty()) {
            bool changed = false;
            for (bool progress = true; progress;) {
                progress = false;
                remaining = 0;
                for (uint32_t f : candidates) {
                    if (!mFaces[f].alive() || !degenerate(f)) continue;
                    if (collapseCheapestEdge(f, false) || dropFlatComponent(f) || collapseCheapestEdge(f, true) || openPinch(f))
                        progress = changed = true;
                    else
                        ++remaining;
                }
            }
            if (!changed) break;
            std::vector<uint32_t> next;
            for (uint32_t f : candidates)
                if (mFaces[f].alive() && degenerate(f)) next.push_back(f);
            for (uint32_t v : moved)
                if (mMeta[v].alive)
                    for (uint32_t c = mMeta[v].head; c != kNone; c = mFaces[c / 3].next[c % 3])
                        if (degenerate(c / 3)) next.push_back(c / 3);
            std::sort(next.begin(), next.end());
            next.erase(std::unique(next.begin(), next.end()), next.end());
            candidates = std::move(next);
            moved.clear();
        }
    };
    settle();
    if (!candidates.empty() && mMaxError < HUGE_VAL) {
        // What no fix within the bound removes (twins on a voxel corner that every collapse near them
        // would move too far, where the pinch does not open) goes past it: a face without area is a
        // defect of the mesh, and the report's largest accepted error says how far past.
        const double bound = mMaxError;
        mMaxError = HUGE_VAL;
        settle();
        mMaxError = bound;
    }
    mMinNormalCos = savedCos;
    mZeroArea = 0.0;
    return remaining;
}

size_t Decimator::retireInterior(size_t rings, double minComponentArea)
{
    const uint32_t slots = uint32_t(mMeta.size());
    // What stays: rings around the open vertices, the seam just closed and every face that is or may
    // become zero-area.
    PooledVector<uint8_t> near(slots, 0);
    std::vector<uint32_t> frontier, next;
    const auto keep = [&](uint32_t v) {
        if (!near[v]) {
            near[v] = 1;
            frontier.push_back(v);
        }
    };
    for (uint32_t v = 0; v < slots; ++v)
        if (mMeta[v].alive && !mMeta[v].final) keep(v);
    for (uint32_t v : mSeam)
        if (mMeta[v].alive) keep(v);
    // mMinPlaneWeight is kMinPlaneWeight voxel faces. The final pass's zero area, 1e-12 of the squared
    // diagonal, is below this one for any surface under ~30,000 voxels across.
    const double mayBecomeZero = kRetireMinArea * mMinPlaneWeight / kMinPlaneWeight;
    for (uint32_t f = 0; f < mFaces.size(); ++f)
        if (mFaces[f].alive() && degenerate(f, mayBecomeZero))
            for (uint32_t v : mFaces[f].v) keep(v);
    for (size_t i = 0; i < rings && !frontier.empty(); ++i) {
        next.clear();
        for (uint32_t v : frontier) {
            neighbours(v, mScratchB);
            for (uint32_t n : mScratchB)
                if (!near[n]) {
                    near[n] = 1;
                    next.push_back(n);
                }
        }
        frontier.swap(next);
    }
    frontier = {};
    next = {};
    // Components by union-find: small ones stay whole (dropSmallComponents, pruneComponents); one with
    // a pinned vertex has retired faces already (so the live faces are all this needs to join).
    const PooledVector<uint32_t> roots = componentRoots(false);
    const auto find = [&](uint32_t v) { return roots[v]; };
    struct Size {
        uint64_t faces = 0;
        double area = 0;
    };
    PooledVector<Size> size(roots.size());
    const bool areas = minComponentArea > 0;  // a bound of 0 passes any area, 0 included
    for (const Face& f : mFaces)
        if (f.alive()) {
            Size& c = size[find(f.v[0])];
            ++c.faces;
            if (areas) c.area += triangleArea(mGeom[f.v[0]].p, mGeom[f.v[1]].p, mGeom[f.v[2]].p);
        }
    for (const auto& pinned : mPinnedAt) size[find(pinned.first)].faces = UINT64_MAX;
    const auto retires = [&](const Face& f) {
        if (near[f.v[0]] || near[f.v[1]] || near[f.v[2]]) return false;
        const Size& c = size[find(f.v[0])];
        return c.faces == UINT64_MAX || (c.faces >= kRetireComponentFaces && c.area >= minComponentArea);
    };
    // Faces in slot order, their corners numbered as they first appear (a pinned one has its number).
    PooledVector<uint32_t> at(slots, kNone);
    for (const auto& [v, i] : mPinnedAt) at[v] = i;
    std::vector<uint32_t> corners;
    size_t retired = 0;
    for (uint32_t f = 0; f < mFaces.size(); ++f) {
        if (!mFaces[f].alive() || !retires(mFaces[f])) continue;
        std::array<uint32_t, 3> t;
        for (int k = 0; k < 3; ++k) {
            const uint32_t v = mFaces[f].v[k];
            if (at[v] == kNone) {
                at[v] = uint32_t(mRetired.points.size());
                const V3& p = mGeom[v].p;
                mRetired.points.emplace_back() = {float(p[0]), float(p[1]), float(p[2])};
                corners.push_back(v);
            }
            t[k] = at[v];
        }
        mRetired.triangles.emplace_back() = t;
        killFace(f);
        ++mFaceCount;  // still a face of the surface
        ++retired;
    }
    if (retired == 0) return 0;
    // A corner without faces here leaves; one with faces stays, pinned. Either way its queue entries
    // and refusals go (a pinned vertex is never queued again).
    for (const auto& pinned : mPinnedAt) corners.push_back(pinned.first);
    // In slot order: the slots freed here are the next ones reused, which the map's order must not decide.
    std::sort(corners.begin(), corners.end());
    for (uint32_t v : corners) {
        if (!mMeta[v].alive) continue;
        if (mMeta[v].head == kNone) {
            killVertex(v);
        } else if (!mMeta[v].pinned) {
            mMeta[v].pinned = true;
            ++mMeta[v].version;
            mPinnedAt.emplace(v, at[v]);
        }
    }
    size_t kept = 0;
    for (const Refused& r : mRefused)
        if (liveFinalPair(r.a, r.b)) mRefused[kept++] = r;
    mRefused.truncate(kept);
    // The slots of what left are reused by the next join's absorb; the queue drops their entries now.
    compactQueue();
    return retired;
}

PooledVector<uint32_t> Decimator::componentRoots(bool withRetired) const
{
    // Union-find over the vertices of live faces and, withRetired, the points of retired faces, which
    // the pinned vertices join.
    const uint32_t slots = uint32_t(mMeta.size());
    PooledVector<uint32_t> parent(slots + (withRetired ? mRetired.points.size() : 0));
    for (uint32_t v = 0; v < parent.size(); ++v) parent[v] = v;
    const auto find = [&](uint32_t v) {
        while (parent[v] != v) v = parent[v] = parent[parent[v]];
        return v;
    };
    const auto join = [&](const std::array<uint32_t, 3>& t, uint32_t base) {
        parent[find(base + t[1])] = find(base + t[0]);
        parent[find(base + t[2])] = find(base + t[0]);
    };
    for (const Face& f : mFaces)
        if (f.alive()) join(f.v, 0);
    if (withRetired) {
        for (size_t i = 0; i < mRetired.triangles.size(); ++i) join(mRetired.triangles[i], slots);
        for (const auto& [v, at] : mPinnedAt) parent[find(slots + at)] = find(v);
    }
    for (uint32_t v = 0; v < parent.size(); ++v) parent[v] = find(v);
    return parent;
}

std::vector<Decimator::Component> Decimator::componentsByArea() const
{
    const PooledVector<uint32_t> roots = componentRoots(true);
    const uint32_t slots = uint32_t(mMeta.size());
    PooledVector<int64_t> index(roots.size(), -1);
    std::vector<Component> comps;
    const auto component = [&](uint32_t root, uint64_t first) -> Component& {
        if (index[root] < 0) {
            index[root] = int64_t(comps.size());
            comps.emplace_back().firstFace = first;
        }
        return comps[size_t(index[root])];
    };
    for (uint32_t f = 0; f < mFaces.size(); ++f) {
        if (!mFaces[f].alive()) continue;
        const auto& v = mFaces[f].v;
        Component& c = component(roots[v[0]], f);
        c.area += triangleArea(mGeom[v[0]].p, mGeom[v[1]].p, mGeom[v[2]].p);
        c.faces.push_back(f);
    }
    for (uint32_t i = 0; i < mRetired.triangles.size(); ++i) {
        const auto& t = mRetired.triangles[i];
        Component& c = component(roots[slots + t[0]], uint64_t(mFaces.size()) + i);
        c.area += triangleArea(mRetired.points[t[0]], mRetired.points[t[1]], mRetired.points[t[2]]);
        c.retired.push_back(i);
    }
    std::sort(comps.begin(), comps.end(), [](const Component& a, const Component& b) {
        return a.area != b.area ? a.area < b.area : a.firstFace < b.firstFace;
    });
    return comps;
}

void Decimator::dropComponent(const Component& c, std::vector<uint32_t>& retiredGone)
{
    std::vector<uint32_t> verts;
    for (uint32_t f : c.faces) {
        for (uint32_t v : mFaces[f].v) verts.push_back(v);
        killFace(f);
    }
    std::sort(verts.begin(), verts.end());
    verts.erase(std::unique(verts.begin(), verts.end()), verts.end());
    for (uint32_t v : verts) killVertex(v);
    retiredGone.insert(retiredGone.end(), c.retired.begin(), c.retired.end());
    mFaceCount -= c.retired.size();
}

void Decimator::dropRetired(const std::vector<uint32_t>& gone)
{
    if (gone.empty()) return;
    PooledVector<uint8_t> stays(mRetired.triangles.size(), 1);
    for (uint32_t i : gone) stays[i] = 0;
    const size_t points = mRetired.points.size();
    PooledVector<uint32_t> renumber(points, kNone);
    for (uint32_t i = 0; i < stays.size(); ++i)
        if (stays[i])
            for (uint32_t p : mRetired.triangles[i]) renumber[p] = 0;
    // The points that stay keep their order.
    RetiredMesh kept;
    for (size_t p = 0; p < points; ++p)
        if (renumber[p] == 0) {
            renumber[p] = uint32_t(kept.points.size());
            kept.points.emplace_back() = mRetired.points[p];
        }
    for (uint32_t i = 0; i < stays.size(); ++i)
        if (stays[i]) {
            const auto& t = mRetired.triangles[i];
            kept.triangles.emplace_back() = {renumber[t[0]], renumber[t[1]], renumber[t[2]]};
        }
    mRetired = std::move(kept);
    // A pinned vertex whose retired faces all went has no point left: its live faces went with them
    // (the same component), so it dies.
    std::vector<uint32_t> orphans;
    for (auto& [v, at] : mPinnedAt) {
        if (renumber[at] == kNone) orphans.push_back(v);
        else at = renumber[at];
    }
    std::sort(orphans.begin(), orphans.end());
    for (uint32_t v : orphans) killVertex(v);
}

size_t Decimator::dropSmallComponents(size_t targetFaces)
{
    if (mFaceCount <= targetFaces) return 0;
    const std::vector<Component> comps = componentsByArea();
    std::vector<uint32_t> retiredGone;
    size_t dropped = 0;
    for (size_t i = 0; i + 1 < comps.size() && mFaceCount > targetFaces; ++i) {
        dropComponent(comps[i], retiredGone);
        ++dropped;
    }
    dropRetired(retiredGone);
    return dropped;
}

size_t Decimator::pruneComponents(double minArea)
{
    const std::vector<Component> comps = componentsByArea();
    std::vector<uint32_t> retiredGone;
    size_t dropped = 0;
    for (; dropped < comps.size() && comps[dropped].area < minArea; ++dropped) dropComponent(comps[dropped], retiredGone);
    dropRetired(retiredGone);
    return dropped;
}

void Decimator::dropDeadEntries()
{
    // A pair of live vertices is still an edge (see decimateTo): no ring walk per entry.
    mHeap.eraseIf([&](const Candidate& c) { return !liveFinalPair(c.a(), c.b); });
}

void Decimator::compactQueue()
{
    dropDeadEntries();
    mHeap.shrinkToFit();
}

void Decimator::retryFolds()
{
    retryRefused([](const Refused& r) { return Refusal(r.why) == Refusal::Folds; });
}

bool Decimator::boundRefusesAnEdge()
{
    // Some pairs the bound turned away before their topology was looked at (decimateTo).
    for (const Refused& r : mRefused) {
        if (Refusal(r.why) != Refusal::Bound || !mMeta[r.a].alive || !mMeta[r.b].alive) continue;
        EdgeLink e;
        Placement places[kPlacements];
        size_t place = 0;
        if (placeCollapse(r.a, r.b, e, places, &place) == Outcome::Collapsed) return true;
    }
    return false;
}

Decimator::Outcome Decimator::placeCollapse(uint32_t a, uint32_t b, EdgeLink& e, Placement places[kPlacements], size_t* place)
{
    if (!edgeMayCollapse(a, b, e)) return Outcome::Refused;
    const size_t count = placements(a, b, places, false);
    size_t p = 0;
    while (p < count && !(facesStayValid(a, b, places[p].p) && facesStayValid(b, a, places[p].p))) ++p;
    if (p == count) return Outcome::Folds;
    *place = p;
    return Outcome::Collapsed;
}

void Decimator::requeueForgotten()
{
    // Every edge again at its cost now, but the refused pairs: they wait for their faces to change.
    // What the dropped entries would have given: a dead one nothing, a stale one its edge at today's
    // cost, and a current one the same entry.
    PooledVector<uint64_t> refused(mRefused.size());
    for (size_t i = 0; i < mRefused.size(); ++i) refused[i] = uint64_t(mRefused[i].a) << 32 | mRefused[i].b;
    std::sort(refused.begin(), refused.end());
    mHeap.clear();
    for (uint32_t v = 0; v < mMeta.size(); ++v) {
        if (!mMeta[v].alive || !mMeta[v].final) continue;
        neighbours(v, mScratchB);
        for (uint32_t n : mScratchB)
            if (n > v && mMeta[n].final && !std::binary_search(refused.begin(), refused.end(), uint64_t(v) << 32 | n))
                push(v, n);
    }
}

void Decimator::requeueAll()
{
    mRefused.clear();
    requeueForgotten();
}

// verticesRead(v) / facesRead(i): vertex v / face i, and every one before it, has been read for the last time.
template <typename VerticesRead, typename FacesRead>
void Decimator::collectMesh(Mesh& m, VerticesRead verticesRead, FacesRead facesRead) const
{
    // Live vertices and faces in slot order (deterministic for a deterministic input sequence), on
    // all threads: every span of slots counts its live records, then writes them from its offset.
    // A span is whole chunks of every array, so the callbacks may free what a span has read while
    // the others still read theirs.
    static_assert(decltype(mGeom)::kChunk == decltype(mMeta)::kChunk && decltype(mMeta)::kChunk == decltype(mFaces)::kChunk,
                  "spans cover whole chunks of every array");
    constexpr size_t kSpan = 4 * decltype(mMeta)::kChunk;
    const auto spans = [](size_t n) { return (n + kSpan - 1) / kSpan; };
    // first[s]: how many live records lie before span s.
    const auto offsets = [&](size_t n, const auto& live) {
        std::vector<size_t> first(spans(n) + 1, 0);
        tbb::parallel_for(size_t(0), spans(n), [&](size_t s) {
            size_t count = 0;
            for (size_t i = s * kSpan; i < std::min(n, (s + 1) * kSpan); ++i) count += live(i);
            first[s + 1] = count;
        });
        std::partial_sum(first.begin(), first.end(), first.begin());
        return first;
    };
    const size_t slots = mMeta.size();
    const std::vector<size_t> firstVertex = offsets(slots, [&](size_t v) { return mMeta[v].alive && !mMeta[v].pinned; });
    const size_t pointsBefore = m.points.size(), trianglesBefore = m.triangles.size();
    m.points.resize(pointsBefore + firstVertex.back());
    std::vector<uint32_t> remap(slots, UINT32_MAX);
    for (const auto& [v, at] : mPinnedAt) remap[v] = at;
    tbb::parallel_for(size_t(0), spans(slots), [&](size_t s) {
        size_t out = pointsBefore + firstVertex[s];
        for (size_t v = s * kSpan; v < std::min(slots, (s + 1) * kSpan); ++v) {
            if (mMeta[v].alive && !mMeta[v].pinned) {
                remap[v] = uint32_t(out);
                const V3& p = mGeom[v].p;
                m.points[out++] = {float(p[0]), float(p[1]), float(p[2])};
            }
            verticesRead(v);
        }
    });
    const size_t faces = mFaces.size();
    const std::vector<size_t> firstFace = offsets(faces, [&](size_t i) { return mFaces[i].alive(); });
    m.triangles.resize(trianglesBefore + firstFace.back());
    tbb::parallel_for(size_t(0), spans(faces), [&](size_t s) {
        size_t out = trianglesBefore + firstFace[s];
        for (size_t i = s * kSpan; i < std::min(faces, (s + 1) * kSpan); ++i) {
            const Face& f = mFaces[i];
            if (f.alive()) m.triangles[out++] = {remap[f.v[0]], remap[f.v[1]], remap[f.v[2]]};
            facesRead(i);
        }
    });
}

Mesh Decimator::mesh() const
{
    Mesh m;
    for (size_t i = 0; i < mRetired.points.size(); ++i) m.points.push_back(mRetired.points[i]);
    for (size_t i = 0; i < mRetired.triangles.size(); ++i) m.triangles.push_back(mRetired.triangles[i]);
    collectMesh(m, [](size_t) {}, [](size_t) {});
    return m;
}

Mesh Decimator::takeMesh()
{
    mHeap = {};
    mRefused = {};
    mOpen = {};
    mSealedOpen = {};
    mFreeVerts = {};
    mFreeFaces = {};
    mDrift = {};
    mAttrQ = {};
    const Stopwatch collection;
    // Exactly the output's size (a vector grown past its capacity holds both copies while it moves),
    // the retired part first, freed as it is copied. Its chunks go back to the pool, whose regions are
    // unmapped as they empty; what the heap holds free meanwhile (every chunk, under AddressSanitizer)
    // is handed back every few megabytes copied.
    Mesh m;
    m.points.reserve(mRetired.points.size() + mVertexCount - mPinnedAt.size());
    m.triangles.reserve(mFaceCount);
    // Written once, in order: in huge pages, a fault for every 2 MiB instead of every 4 KiB.
    adviseHugePages(m.points.data(), m.points.capacity() * sizeof(m.points[0]));
    adviseHugePages(m.triangles.data(), m.triangles.capacity() * sizeof(m.triangles[0]));
    constexpr size_t kTrimEvery = size_t(1) << 20;  // records of 12 bytes
    const auto moveOut = [](auto& from, auto& to) {
        drainInRuns(from, [](const auto&) {}, [&](const auto& x) {
            to.push_back(x);
            if (to.size() % kTrimEvery == 0) malloc_trim(0);
        });
    };
    moveOut(mRetired.points, m.points);
    moveOut(mRetired.triangles, m.triangles);
    mRetired = {};
    malloc_trim(0);
    collectMesh(
        m,
        [this](size_t v) {
            mGeom.releaseThrough(v);
            mMeta.releaseThrough(v);
        },
        [this](size_t i) { mFaces.releaseThrough(i); });
    const double parallel = mParallelSeconds + collection.seconds();
    *this = Decimator{};
    mParallelSeconds = parallel;
    return m;
}

} // namespace vdb_isosimp
