#include "mesh_error.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

namespace vdb_isosimp::eval {
namespace {

using Vec = std::array<double, 3>;

Vec toDouble(const std::array<float, 3>& p) { return {p[0], p[1], p[2]}; }
Vec sub(const Vec& a, const Vec& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
Vec madd(const Vec& a, const Vec& d, double t) { return {a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]}; }
double dot(const Vec& a, const Vec& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
double dist2(const Vec& a, const Vec& b) { const Vec d = sub(a, b); return dot(d, d); }

Vec closestOnSegment(const Vec& p, const Vec& a, const Vec& b) {
    const Vec ab = sub(b, a);
    const double len2 = dot(ab, ab);
    if (!(len2 > 0)) return a;
    return madd(a, ab, std::clamp(dot(sub(p, a), ab) / len2, 0.0, 1.0));
}

Vec closestOnEdges(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
    Vec best = closestOnSegment(p, a, b);
    for (const Vec& q : {closestOnSegment(p, b, c), closestOnSegment(p, c, a)})
        if (dist2(p, q) < dist2(p, best)) best = q;
    return best;
}

void checkIndices(const Mesh& mesh, const char* what) {
    const size_t n = mesh.points.size();
    for (size_t f = 0; f < mesh.triangles.size(); ++f)
        for (uint32_t v : mesh.triangles[f])
            if (v >= n)
                throw std::invalid_argument(std::string(what) + ": triangle " + std::to_string(f) +
                                            " references vertex " + std::to_string(v) + " of " + std::to_string(n));
}

// Counter-based random numbers: SplitMix64's finaliser applied to (seed, counter), so a sample's
// randomness depends only on its index, never on which thread draws it.
uint64_t mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
}
double uniform01(uint64_t seed, uint64_t counter) {
    const uint64_t bits = mix64(mix64(seed) + (counter + 1) * 0x9e3779b97f4a7c15ULL);
    return double(bits >> 11) * 0x1.0p-53; // [0, 1)
}

constexpr size_t kLeafSize = 4;
constexpr size_t kParallelBuild = 1 << 16; // subtrees this large are built as parallel tasks
constexpr size_t kSampleChunk = 1024;      // triangles per sampling chunk (fixed: determinism)

// Nodes in a subtree of n triangles under median splitting; deterministic, so both children's
// positions in the depth-first array are known before either is built. Only two sizes (floor and
// ceil) occur per level, so the memo stays tiny.
size_t subtreeNodes(size_t n, std::map<size_t, size_t>& memo) {
    if (n <= kLeafSize) return 1;
    const auto it = memo.find(n);
    if (it != memo.end()) return it->second;
    const size_t count = 1 + subtreeNodes(n / 2, memo) + subtreeNodes(n - n / 2, memo);
    memo[n] = count;
    return count;
}

} // namespace

std::array<double, 3> closestPointOnTriangle(const Vec& p, const Vec& a, const Vec& b, const Vec& c) {
    // Voronoi-region walk: vertex regions, then edge regions, then the interior. A denominator that
    // is not positive can only come from a degenerate triangle; the edge fallback handles those.
    const Vec ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
    const double d1 = dot(ab, ap), d2 = dot(ac, ap);
    if (d1 <= 0 && d2 <= 0) return a;
    const Vec bp = sub(p, b);
    const double d3 = dot(ab, bp), d4 = dot(ac, bp);
    if (d3 >= 0 && d4 <= d3) return b;
    const double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        const double den = d1 - d3;
        return den > 0 ? madd(a, ab, d1 / den) : closestOnEdges(p, a, b, c);
    }
    const Vec cp = sub(p, c);
    const double d5 = dot(ab, cp), d6 = dot(ac, cp);
    if (d6 >= 0 && d5 <= d6) return c;
    const double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        const double den = d2 - d6;
        return den > 0 ? madd(a, ac, d2 / den) : closestOnEdges(p, a, b, c);
    }
    const double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        const double den = (d4 - d3) + (d5 - d6);
        return den > 0 ? madd(b, sub(c, b), (d4 - d3) / den) : closestOnEdges(p, a, b, c);
    }
    const double den = va + vb + vc;
    if (!(den > 0)) return closestOnEdges(p, a, b, c);
    const double v = vb / den, w = vc / den;
    return {a[0] + ab[0] * v + ac[0] * w, a[1] + ab[1] * v + ac[1] * w, a[2] + ab[2] * v + ac[2] * w};
}

// ----------------------------------------------------------------------------------------------
// TriangleBVH

namespace {
// The build sorts these in place: centroid next to the triangle index keeps the median
// partitioning on contiguous memory (16 bytes per triangle, freed after the build).
struct BuildItem {
    float centroid[3];
    uint32_t triangle;
};
} // namespace

// subtreeNodes(n) memoises every subtree size the build will meet (it recurses through the same
// sizes), so the parallel build only reads the map.
struct TriangleBVH::BuildContext {
    std::vector<BuildItem> items;
    std::map<size_t, size_t> subtreeNodes;
    size_t nodes(size_t n) const { return n <= kLeafSize ? 1 : subtreeNodes.at(n); }
};

TriangleBVH::TriangleBVH(const Mesh& mesh) : mesh_(mesh) {
    checkIndices(mesh, "TriangleBVH");
    const size_t n = mesh.triangles.size();
    if (n == 0) throw std::invalid_argument("TriangleBVH: mesh has no triangles");
    if (n > UINT32_MAX / 2) throw std::invalid_argument("TriangleBVH: too many triangles");

    BuildContext ctx;
    ctx.items.resize(n);
    tbb::parallel_for(size_t(0), n, [&](size_t t) {
        const auto& tri = mesh.triangles[t];
        for (size_t k = 0; k < 3; ++k)
            ctx.items[t].centroid[k] = (mesh.points[tri[0]][k] + mesh.points[tri[1]][k] + mesh.points[tri[2]][k]) / 3.0f;
        ctx.items[t].triangle = uint32_t(t);
    });
    nodes_.resize(subtreeNodes(n, ctx.subtreeNodes));
    build(0, 0, n, ctx);
    tris_.resize(n);
    for (size_t i = 0; i < n; ++i) tris_[i] = ctx.items[i].triangle;
}

void TriangleBVH::build(uint32_t node, size_t begin, size_t end, BuildContext& ctx) {
    auto& items = ctx.items;
    Node& nd = nodes_[node];
    const size_t n = end - begin;
    if (n <= kLeafSize) {
        for (size_t k = 0; k < 3; ++k) {
            nd.lo[k] = std::numeric_limits<float>::infinity();
            nd.hi[k] = -std::numeric_limits<float>::infinity();
        }
        for (size_t i = begin; i < end; ++i)
            for (uint32_t v : mesh_.triangles[items[i].triangle])
                for (size_t k = 0; k < 3; ++k) {
                    nd.lo[k] = std::min(nd.lo[k], mesh_.points[v][k]);
                    nd.hi[k] = std::max(nd.hi[k], mesh_.points[v][k]);
                }
        nd.index = uint32_t(begin);
        nd.count = uint32_t(n);
        return;
    }

    // Split at the median centroid along the axis where the centroids spread most.
    float lo[3], hi[3];
    for (size_t k = 0; k < 3; ++k) {
        lo[k] = std::numeric_limits<float>::infinity();
        hi[k] = -std::numeric_limits<float>::infinity();
    }
    for (size_t i = begin; i < end; ++i)
        for (size_t k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], items[i].centroid[k]);
            hi[k] = std::max(hi[k], items[i].centroid[k]);
        }
    size_t axis = 0;
    for (size_t k = 1; k < 3; ++k)
        if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
    const size_t mid = begin + n / 2;
    // Ties broken by triangle index: a strict total order makes the partition reproducible.
    std::nth_element(items.begin() + long(begin), items.begin() + long(mid), items.begin() + long(end),
                     [axis](const BuildItem& x, const BuildItem& y) {
                         const float cx = x.centroid[axis], cy = y.centroid[axis];
                         return cx < cy || (cx == cy && x.triangle < y.triangle);
                     });

    const uint32_t left = node + 1;
    const uint32_t right = uint32_t(left + ctx.nodes(n / 2));
    if (n >= kParallelBuild)
        tbb::parallel_invoke([&] { build(left, begin, mid, ctx); },
                             [&] { build(right, mid, end, ctx); });
    else {
        build(left, begin, mid, ctx);
        build(right, mid, end, ctx);
    }
    const Node &l = nodes_[left], &r = nodes_[right];
    for (size_t k = 0; k < 3; ++k) {
        nd.lo[k] = std::min(l.lo[k], r.lo[k]);
        nd.hi[k] = std::max(l.hi[k], r.hi[k]);
    }
    nd.index = right;
    nd.count = 0;
}

size_t TriangleBVH::memoryBytes() const {
    return nodes_.capacity() * sizeof(Node) + tris_.capacity() * sizeof(uint32_t);
}

double TriangleBVH::triangleDistanceSquared(uint32_t tri, const Vec& p, Vec& closest) const {
    const auto& t = mesh_.triangles[tri];
    closest = closestPointOnTriangle(p, toDouble(mesh_.points[t[0]]), toDouble(mesh_.points[t[1]]),
                                     toDouble(mesh_.points[t[2]]));
    return dist2(p, closest);
}

TriangleBVH::Hit TriangleBVH::nearest(const Vec& p) const {
    auto boxDistance2 = [&p](const Node& nd) {
        double d2 = 0;
        for (size_t k = 0; k < 3; ++k) {
            const double d = std::max({double(nd.lo[k]) - p[k], 0.0, p[k] - double(nd.hi[k])});
            d2 += d * d;
        }
        return d2;
    };

    Hit hit{std::numeric_limits<double>::infinity(), 0, {0, 0, 0}};
    // Depth-first, nearer child first; a stack entry keeps its box distance so it can be skipped
    // once a closer triangle has been found. Median splits keep the depth near log2(n / 4).
    struct Entry {
        uint32_t node;
        double d2;
    };
    Entry stack[96];
    int top = 0;
    stack[top++] = {0, boxDistance2(nodes_[0])};
    while (top > 0) {
        const Entry e = stack[--top];
        if (e.d2 >= hit.distanceSquared) continue;
        const Node& nd = nodes_[e.node];
        if (nd.count > 0) {
            Vec q;
            for (uint32_t i = nd.index; i < nd.index + nd.count; ++i) {
                const double d2 = triangleDistanceSquared(tris_[i], p, q);
                if (d2 < hit.distanceSquared) hit = {d2, tris_[i], q};
            }
            continue;
        }
        const uint32_t l = e.node + 1, r = nd.index;
        const double dl = boxDistance2(nodes_[l]), dr = boxDistance2(nodes_[r]);
        // Push the farther child first so the nearer one is popped next.
        if (dl <= dr) {
            stack[top++] = {r, dr};
            stack[top++] = {l, dl};
        } else {
            stack[top++] = {l, dl};
            stack[top++] = {r, dr};
        }
    }
    return hit;
}

// ----------------------------------------------------------------------------------------------
// Sampling

size_t defaultSampleCount(size_t faces) { return std::max<size_t>(1000000, faces); }

namespace {

double triangleArea(const Mesh& m, size_t f) {
    const auto& t = m.triangles[f];
    const Vec a = toDouble(m.points[t[0]]);
    const Vec ab = sub(toDouble(m.points[t[1]]), a), ac = sub(toDouble(m.points[t[2]]), a);
    const Vec n{ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
    return 0.5 * std::sqrt(dot(n, n));
}

double bboxDiagonal(const Mesh& m) {
    std::vector<char> used(m.points.size(), 0);
    for (const auto& t : m.triangles) used[t[0]] = used[t[1]] = used[t[2]] = 1;
    Vec lo{HUGE_VAL, HUGE_VAL, HUGE_VAL}, hi{-HUGE_VAL, -HUGE_VAL, -HUGE_VAL};
    bool any = false;
    for (size_t v = 0; v < m.points.size(); ++v) {
        if (!used[v]) continue;
        any = true;
        for (size_t k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], double(m.points[v][k]));
            hi[k] = std::max(hi[k], double(m.points[v][k]));
        }
    }
    return any ? std::sqrt(dist2(lo, hi)) : 0.0;
}

} // namespace

DistanceStats sampleDistance(const Mesh& A, const TriangleBVH& bvh, size_t samples, uint64_t seed) {
    checkIndices(A, "sampleDistance");
    const size_t F = A.triangles.size();
    if (samples == 0) samples = defaultSampleCount(F);

    // Serial pass: the running area at each chunk start. Chunks later re-add the same areas in
    // the same order from that value, so every triangle sees bit-identical cumulative areas.
    const size_t nChunks = (F + kSampleChunk - 1) / kSampleChunk;
    std::vector<double> chunkStart(nChunks + 1, 0.0);
    double total = 0;
    for (size_t c = 0; c < nChunks; ++c) {
        chunkStart[c] = total;
        const size_t end = std::min(F, (c + 1) * kSampleChunk);
        for (size_t f = c * kSampleChunk; f < end; ++f) total += triangleArea(A, f);
    }
    chunkStart[nChunks] = total;
    if (!(total > 0) || !std::isfinite(total))
        throw std::invalid_argument("sampleDistance: the sampled mesh has no area");

    // Sample k lies at cumulative area (k + offset) * total / samples; a triangle covering
    // [c0, c1) owns samples firstSample(c0) .. firstSample(c1) - 1.
    const double offset = uniform01(seed, ~uint64_t(0));
    const double scale = double(samples) / total;
    auto firstSample = [&](double cumulative) {
        const double k = std::ceil(cumulative * scale - offset);
        return k <= 0 ? size_t(0) : std::min(samples, size_t(k));
    };

    struct Partial {
        double sum = 0, sum2 = 0, max = 0;
        size_t count = 0;
    };
    std::vector<Partial> partial(nChunks);
    tbb::parallel_for(size_t(0), nChunks, [&](size_t c) {
        Partial acc;
        double cumulative = chunkStart[c];
        const size_t end = std::min(F, (c + 1) * kSampleChunk);
        for (size_t f = c * kSampleChunk; f < end; ++f) {
            const size_t k0 = firstSample(cumulative);
            cumulative += triangleArea(A, f);
            const size_t k1 = f + 1 == F ? samples : firstSample(cumulative);
            if (k0 >= k1) continue;
            const auto& t = A.triangles[f];
            const Vec a = toDouble(A.points[t[0]]), b = toDouble(A.points[t[1]]), cc = toDouble(A.points[t[2]]);
            for (size_t k = k0; k < k1; ++k) {
                // Uniform point in the triangle: sqrt-warped barycentrics (Osada et al. 2002).
                const double s = std::sqrt(uniform01(seed, 2 * uint64_t(k)));
                const double r = uniform01(seed, 2 * uint64_t(k) + 1);
                const double wa = 1 - s, wb = s * (1 - r), wc = s * r;
                const Vec p{wa * a[0] + wb * b[0] + wc * cc[0], wa * a[1] + wb * b[1] + wc * cc[1],
                            wa * a[2] + wb * b[2] + wc * cc[2]};
                const double d = std::sqrt(bvh.nearest(p).distanceSquared);
                acc.sum += d;
                acc.sum2 += d * d;
                acc.max = std::max(acc.max, d);
                ++acc.count;
            }
        }
        partial[c] = acc;
    });

    DistanceStats out;
    double sum = 0, sum2 = 0;
    for (const Partial& p : partial) {
        sum += p.sum;
        sum2 += p.sum2;
        out.max = std::max(out.max, p.max);
        out.samples += p.count;
    }
    out.mean = sum / double(out.samples);
    out.rms = std::sqrt(sum2 / double(out.samples));

    // The one-sided Hausdorff distance is often reached at a vertex (a corner sticking out), which
    // area samples hit with probability zero; so the max also covers every vertex of a face of A with
    // area. Vertices of zero-area faces alone are left out: a voxel exactly at the iso-value amid
    // values on one side gives a closed component of zero area, a single point of the level set that
    // carries no surface, which simplified surfaces (no zero-area faces) do not keep.
    std::vector<char> used(A.points.size(), 0);
    for (size_t f = 0; f < F; ++f)
        if (triangleArea(A, f) > 0) {
            const auto& t = A.triangles[f];
            used[t[0]] = used[t[1]] = used[t[2]] = 1;
        }
    const size_t V = A.points.size();
    const size_t nVChunks = (V + kSampleChunk - 1) / kSampleChunk;
    std::vector<double> vmax(nVChunks, 0.0);
    std::vector<size_t> vcount(nVChunks, 0);
    tbb::parallel_for(size_t(0), nVChunks, [&](size_t c) {
        const size_t end = std::min(V, (c + 1) * kSampleChunk);
        for (size_t v = c * kSampleChunk; v < end; ++v) {
            if (!used[v]) continue;
            vmax[c] = std::max(vmax[c], std::sqrt(bvh.nearest(toDouble(A.points[v])).distanceSquared));
            ++vcount[c];
        }
    });
    for (size_t c = 0; c < nVChunks; ++c) {
        out.max = std::max(out.max, vmax[c]);
        out.vertexQueries += vcount[c];
    }
    out.diagonal = bboxDiagonal(A);
    return out;
}

DistanceStats sampleDistance(const Mesh& A, const Mesh& B, size_t samples, uint64_t seed) {
    const TriangleBVH bvh(B);
    return sampleDistance(A, bvh, samples, seed);
}

SymmetricDistance symmetricDistance(const Mesh& A, const Mesh& B, size_t samples, uint64_t seed) {
    SymmetricDistance d;
    d.ab = sampleDistance(A, B, samples, seed);
    d.ba = sampleDistance(B, A, samples, seed);
    d.hausdorff = std::max(d.ab.max, d.ba.max);
    return d;
}

SurfaceError surfaceError(const Mesh& full, const Mesh& simplified, size_t samples, uint64_t seed)
{
    const SymmetricDistance d = symmetricDistance(full, simplified, samples, seed);
    return {100 * d.ab.rms / d.ab.diagonal, 100 * d.hausdorff / d.ab.diagonal};
}

} // namespace vdb_isosimp::eval
